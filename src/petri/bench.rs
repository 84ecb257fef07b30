//! `vl petri bench`: the corpus explored and analysed, beside the
//! figures verifypn recorded on it.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;
use vl_petri::{BenchRow, Manifest, bench_model, from_pnml};

use crate::BadInput;
use crate::alloc::Counting;
use crate::report::{Report, Table, emit};
use crate::shipped::{CORPUS_MANIFEST, corpus_model, read_input};

use super::io::load;

/// When and where the manifest's verifypn figures were recorded.
const VERIFYPN_RECORDED: &str = "recorded 2026-11-21, Debian 12, 2 cores";

pub(super) fn bench_command(
    corpus: Option<&Path>,
    tier: &str,
    only: &[String],
    json: bool,
) -> Result<ExitCode> {
    let manifest_text = match corpus {
        Some(dir) => read_input(&dir.join("manifest.csv"))?,
        None => CORPUS_MANIFEST.to_owned(),
    };
    let manifest = Manifest::parse(&manifest_text).map_err(|e| BadInput(e.to_string()))?;
    let models: Vec<_> = manifest
        .tier(tier)
        .filter(|m| only.is_empty() || only.iter().any(|name| name == m.name()))
        .collect();
    if models.is_empty() {
        return Err(BadInput(format!(
            "no {tier} model{} in the manifest",
            if only.is_empty() {
                String::new()
            } else {
                format!(" named {}", only.join(", "))
            }
        ))
        .into());
    }
    let mut rows: Vec<BenchLine> = Vec::new();
    for model in models {
        let (net, file) = match corpus {
            Some(dir) => (load(&dir.join(model.pnml()))?, None),
            None => {
                let text = corpus_model(model.pnml()).ok_or_else(|| {
                    BadInput(format!(
                        "{} is not built in (only the large tier is): \
                         give --corpus tests/petri-corpus",
                        model.name()
                    ))
                })?;
                let net = from_pnml(text).map_err(|e| anyhow::anyhow!("{}: {e}", model.name()))?;
                (net, Some(text))
            }
        };
        if !json {
            eprint!("{} … ", model.name());
        }
        let row = bench_model(model, &net, &Counting)
            .map_err(|e| anyhow::anyhow!("{}: {e}", model.name()))?;
        let whole = match (corpus, file) {
            (Some(dir), _) => analyze_process(&dir.join(model.pnml()))?,
            (None, Some(text)) => {
                let path = std::env::temp_dir().join(format!(
                    "vl-bench-{}-{}.pnml",
                    std::process::id(),
                    model.name()
                ));
                std::fs::write(&path, text)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                let whole = analyze_process(&path);
                let _ = std::fs::remove_file(&path);
                whole?
            }
            (None, None) => unreachable!("a built-in model has its text"),
        };
        if !json {
            eprintln!(
                "{:.2} s counting, {:.2} s analysing, {:.2} s analysing as a process",
                row.count_seconds, row.analyze_seconds, whole.0
            );
        }
        rows.push(BenchLine {
            row,
            analyze_process_seconds: whole.0,
            analyze_process_peak_mb: whole.1,
        });
    }
    emit(&Bench(rows), json)?;
    Ok(ExitCode::SUCCESS)
}

/// Every model's line, printed as one table.
#[derive(Serialize)]
#[serde(transparent)]
struct Bench(Vec<BenchLine>);

/// One model's benchmark: exploring and analysing in this process, and
/// `vl petri analyze` on it as a whole process, as a user runs it.
#[derive(Serialize)]
struct BenchLine {
    #[serde(flatten)]
    row: BenchRow,
    /// Wall time of `vl petri analyze MODEL --json`, start to exit.
    analyze_process_seconds: f64,
    /// Its peak resident memory, MB.
    analyze_process_peak_mb: f64,
}

/// Runs `vl petri analyze` on `model` as a separate process: its wall time,
/// s, and its peak resident memory, MB (as it reports it).
fn analyze_process(model: &Path) -> Result<(f64, f64)> {
    let me = std::env::current_exe().context("cannot find the vl binary")?;
    let started = Instant::now();
    let out = std::process::Command::new(me)
        .args(["petri", "analyze", "--json"])
        .arg(model)
        .output()
        .context("cannot run vl petri analyze")?;
    let seconds = started.elapsed().as_secs_f64();
    anyhow::ensure!(
        out.status.success(),
        "vl petri analyze {} failed: {}",
        model.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&out.stdout).context("vl petri analyze printed no JSON")?;
    let peak = report["peak_resident_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6;
    Ok((seconds, peak))
}

impl Report for Bench {
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
