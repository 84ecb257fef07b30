//! Speed on the Model Checking Contest's models: the corpus manifest with
//! each model's certified answers, and one model's exploration and
//! analysis timed against them (`vl petri bench`; the corpus test reads
//! the same manifest).

use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

use crate::{ExploreError, Net, Options, analyze_net, count_states};
use vl_report::{PeakMemory, Report, Table};

/// The corpus's `manifest.csv`: one row per model.
#[derive(Debug, Clone)]
pub struct Manifest {
    pub models: Vec<CorpusModel>,
}

/// One model of the corpus and what is certified about it, by column.
#[derive(Debug, Clone)]
pub struct CorpusModel {
    columns: Vec<(String, String)>,
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ManifestError {
    #[error("the manifest has no header line")]
    Empty,
    #[error("the manifest has no column '{0}'")]
    MissingColumn(&'static str),
    #[error("manifest line {line} has {got} columns, not {want}")]
    Ragged {
        line: usize,
        got: usize,
        want: usize,
    },
}

/// Columns every row must have.
const REQUIRED: [&str; 3] = ["model", "tier", "pnml"];

impl Manifest {
    /// Parses the CSV. Only the last column (the source, quoted) may hold commas.
    pub fn parse(text: &str) -> Result<Manifest, ManifestError> {
        let mut lines = text.lines();
        let header: Vec<&str> = lines
            .next()
            .ok_or(ManifestError::Empty)?
            .split(',')
            .collect();
        for column in REQUIRED {
            if !header.contains(&column) {
                return Err(ManifestError::MissingColumn(column));
            }
        }
        let models = lines
            .enumerate()
            .filter(|(_, line)| !line.trim().is_empty())
            .map(|(i, line)| {
                let cells: Vec<&str> = line.splitn(header.len(), ',').collect();
                if cells.len() != header.len() {
                    return Err(ManifestError::Ragged {
                        line: i + 2,
                        got: cells.len(),
                        want: header.len(),
                    });
                }
                let columns = header
                    .iter()
                    .zip(cells)
                    .map(|(h, c)| ((*h).to_owned(), c.to_owned()))
                    .collect();
                Ok(CorpusModel { columns })
            })
            .collect::<Result<_, _>>()?;
        Ok(Manifest { models })
    }

    /// The models of one tier (small, medium, large).
    pub fn tier<'a>(&'a self, tier: &'a str) -> impl Iterator<Item = &'a CorpusModel> + 'a {
        self.models.iter().filter(move |m| m.tier() == tier)
    }
}

impl CorpusModel {
    /// The cell in `column`, if the manifest has that column.
    pub fn get(&self, column: &str) -> Option<&str> {
        self.columns
            .iter()
            .find(|(h, _)| h == column)
            .map(|(_, v)| v.as_str())
    }

    /// The cell in `column` as a count.
    pub fn count(&self, column: &str) -> Option<usize> {
        self.get(column)?.parse().ok()
    }

    pub fn name(&self) -> &str {
        self.get("model").expect("checked on parsing")
    }

    pub fn tier(&self) -> &str {
        self.get("tier").expect("checked on parsing")
    }

    /// The model's PNML file, relative to the corpus directory.
    pub fn pnml(&self) -> &str {
        self.get("pnml").expect("checked on parsing")
    }
}

/// One model's benchmark figures: the two jobs `vl petri` offers, each
/// timed whole in this process.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    pub model: String,
    pub states: usize,
    pub edges: usize,
    /// The breadth-first counts (on one thread and on two) and the
    /// depth-first analysis found the same states and edges.
    pub agree: bool,
    pub certified_states: Option<usize>,
    pub certified_edges: Option<usize>,
    /// Counting states, edges and bounds (`vl petri states`, like `verifypn -e`).
    pub count_seconds: f64,
    /// The same on two threads (`vl petri states --threads 2`).
    pub count_seconds_on_two: f64,
    /// The most heap bytes live at once while counting.
    pub count_peak_heap_bytes: usize,
    /// The whole analysis (`vl petri analyze`): liveness, reversibility,
    /// deadlocks and bounds, with no stored graph. Its memory is mapped
    /// from the system, not taken from the heap: the memory to compare is
    /// a whole process's.
    pub analyze_seconds: f64,
    pub states_per_second: f64,
    pub bytes_per_marking: usize,
    /// verifypn 3.1.1's `-e` time and peak resident memory as the manifest
    /// recorded them (a whole process, on a 2-core machine like CI's):
    /// not measured in this run, so never divided by what is.
    pub verifypn_recorded_seconds: Option<f64>,
    pub verifypn_recorded_peak_kb: Option<u64>,
}

impl BenchRow {
    /// Whether both searches found the certified numbers of states and edges.
    pub fn certified(&self) -> bool {
        self.agree
            && self.certified_states == Some(self.states)
            && self.certified_edges == Some(self.edges)
    }
}

/// Counts and analyses `net`, the corpus's `model`, timing each.
pub fn bench_model(
    model: &CorpusModel,
    net: &Net,
    memory: &dyn PeakMemory,
) -> Result<BenchRow, ExploreError> {
    memory.reset_peak();
    let started = Instant::now();
    let count = count_states(net, Options::default(), 1)?;
    let count_seconds = started.elapsed().as_secs_f64();
    let count_peak_heap_bytes = memory.peak_bytes();
    let started = Instant::now();
    let on_two = count_states(net, Options::default(), 2)?;
    let count_seconds_on_two = started.elapsed().as_secs_f64();
    let analyzed = Instant::now();
    let analysis = analyze_net(net, Options::default())?;
    let analyze_seconds = analyzed.elapsed().as_secs_f64();
    let verifypn_recorded_seconds = model
        .get("verifypn_wall_s")
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|&v| v > 0.0);
    let verifypn_recorded_peak_kb = model
        .get("verifypn_rss_kb")
        .and_then(|v| v.parse::<u64>().ok())
        .filter(|&v| v > 0);
    Ok(BenchRow {
        model: model.name().to_owned(),
        states: count.states,
        edges: count.edges,
        agree: (count.states, count.edges) == (analysis.states, analysis.edges)
            && (on_two.states, on_two.edges) == (count.states, count.edges),
        certified_states: model.count("states"),
        certified_edges: model.count("rg_edges"),
        count_seconds,
        count_seconds_on_two,
        count_peak_heap_bytes,
        analyze_seconds,
        states_per_second: count.states as f64 / count_seconds,
        bytes_per_marking: count.bytes_per_marking,
        verifypn_recorded_seconds,
        verifypn_recorded_peak_kb,
    })
}

/// When and where the manifest's verifypn figures were recorded.
const VERIFYPN_RECORDED: &str = "recorded 2026-11-21, Debian 12, 2 cores";

/// Every model's line, printed as one table.
#[derive(Debug, Serialize)]
#[serde(transparent)]
pub struct BenchReport(pub Vec<BenchLine>);

/// One model's benchmark: exploring and analysing in this process, and
/// `vl petri analyze` on it as a whole process, as a user runs it.
#[derive(Debug, Serialize)]
pub struct BenchLine {
    #[serde(flatten)]
    pub row: BenchRow,
    /// Wall time of `vl petri analyze MODEL --json`, start to exit.
    pub analyze_process_seconds: f64,
    /// Its peak resident memory, MB.
    pub analyze_process_peak_mb: f64,
}

impl Report for BenchReport {
    fn table(&self) -> Table {
        let mut table = Table::columns(&[
            "model",
            "states",
            "ok",
            "states s",
            "2 threads",
            "states/s",
            "heap MB",
            "B/marking",
            "analyze s",
            "process s",
            "process MB",
            "verifypn s*",
            "verifypn MB*",
        ]);
        for line in &self.0 {
            let r = &line.row;
            table.row(vec![
                r.model.clone(),
                r.states.to_string(),
                if r.certified() { "yes" } else { "NO" }.to_owned(),
                format!("{:.2}", r.count_seconds),
                format!(
                    "{:.2} ({:.2}×)",
                    r.count_seconds_on_two,
                    r.count_seconds / r.count_seconds_on_two
                ),
                format!("{:.0}", r.states_per_second),
                format!("{:.0}", r.count_peak_heap_bytes as f64 / 1e6),
                r.bytes_per_marking.to_string(),
                format!("{:.2}", r.analyze_seconds),
                format!("{:.2}", line.analyze_process_seconds),
                format!("{:.0}", line.analyze_process_peak_mb),
                r.verifypn_recorded_seconds
                    .map_or("–".to_owned(), |v| format!("{v:.2}")),
                r.verifypn_recorded_peak_kb
                    .map_or("–".to_owned(), |v| format!("{:.0}", v as f64 / 1e3)),
            ]);
        }
        table
            .note("ok: counting (on one thread and on two) and analysing all found the certified numbers of states and edges.")
            .note("states s, analyze s: `vl petri states` and `vl petri analyze` as jobs in this process, one thread; 2 threads: `vl petri states --threads 2`, and its speed-up; heap MB: the most live at once while counting on one;")
            .note("process s, process MB: `vl petri analyze MODEL --json` as a whole process (wall time, peak resident memory: the analysis maps its memory from the system, outside the heap).")
            .note(format!(
                "* recorded, not measured in this run: TAPAAL verifypn 3.1.1 -e as a whole process on a 2-core machine \
                 like CI's, from the corpus manifest ({VERIFYPN_RECORDED}). Recorded times have differed from \
                 side-by-side runs by -14 % to +40 %, so no ratio is printed: bench/petri_vs_verifypn.sh runs both \
                 side by side"
            ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_manifest_reads_by_column_with_a_quoted_last_one() {
        let text = "model,tier,pnml,states,source\n\
                    A,small,a/model.pnml,13,\"x, y (z)\"\n\
                    B,large,b/model.pnml,,\"w\"\n";
        let m = Manifest::parse(text).unwrap();
        assert_eq!(m.models.len(), 2);
        assert_eq!(m.models[0].get("source"), Some("\"x, y (z)\""));
        assert_eq!(m.models[0].count("states"), Some(13));
        assert_eq!(m.models[1].count("states"), None);
        assert_eq!(
            m.tier("large").map(CorpusModel::name).collect::<Vec<_>>(),
            ["B"]
        );
        assert_eq!(
            Manifest::parse("model,pnml\n").unwrap_err(),
            ManifestError::MissingColumn("tier")
        );
        assert!(matches!(
            Manifest::parse("model,tier,pnml\nA,small\n"),
            Err(ManifestError::Ragged { line: 2, .. })
        ));
    }
}
