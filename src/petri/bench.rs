//! `vl petri bench`: the corpus explored and analysed, beside the
//! figures verifypn recorded on it.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use vl_petri::{BenchLine, BenchReport, Manifest, bench_model};

use crate::report::emit;
use crate::shipped::{CORPUS_MANIFEST, corpus_model, read_input};
use crate::{BadInput, bad_input};
use vl_report::Counting;

use super::io::load;

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
    let manifest = Manifest::parse(&manifest_text).map_err(bad_input)?;
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
        if corpus.is_none() && corpus_model(model.pnml()).is_none() {
            return Err(BadInput(format!(
                "{} is not built in (only the large tier is): give --corpus assets/petri-corpus",
                model.name()
            ))
            .into());
        }
        // A built-in model is read by its path in the repository.
        let path = corpus
            .unwrap_or(Path::new("assets/petri-corpus"))
            .join(model.pnml());
        let net = load(&path)?;
        if !json {
            eprint!("{} … ", model.name());
        }
        let row = bench_model(model, &net, &Counting)
            .map_err(|e| anyhow::anyhow!("{}: {e}", model.name()))?;
        let whole = analyze_process(&path)?;
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
    emit(&BenchReport(rows), json)?;
    Ok(ExitCode::SUCCESS)
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
