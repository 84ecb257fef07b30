//! `vl petri states`: what exploration alone finds, as `verifypn -e`
//! reports it.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use vl_petri::{StatesReport, count_states};

use crate::report::emit;

use super::io::{cost_since, load, with_progress};

pub(super) fn states_command(
    path: &Path,
    json: bool,
    max_states: usize,
    threads: usize,
) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    let found = with_progress(path, max_states, |options| {
        count_states(&net, options, threads)
    })?;
    emit(&StatesReport::of(&net, &found, cost_since(started)), json)?;
    Ok(ExitCode::SUCCESS)
}
