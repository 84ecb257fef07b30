//! `vl petri analyze`: boundedness, safeness, deadlocks, liveness,
//! reversibility and the flow bases, as vl-petri's verdict finds them.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use vl_petri::{AnalysisReport, verdict};

use crate::report::emit;

use super::io::{cost_since, load, with_progress};

pub(super) fn analyze_command(path: &Path, json: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    let found = with_progress(path, max_states, |options| verdict(&net, options))?;
    emit(&AnalysisReport::of(&net, found, cost_since(started)), json)?;
    Ok(ExitCode::SUCCESS)
}
