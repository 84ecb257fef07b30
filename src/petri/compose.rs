//! `vl petri compose`: nets composed synchronously on shared labels.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use vl_petri::{compose, fuse_parallel_places, to_pnml};

use crate::report::count;

use super::io::{load, write_file};

pub(super) fn compose_command(paths: &[PathBuf], fuse: bool, output: &Path) -> Result<ExitCode> {
    let nets = paths.iter().map(|p| load(p)).collect::<Result<Vec<_>>>()?;
    let mut net = compose(&nets)?;
    let before = net.places.len();
    if fuse {
        net = fuse_parallel_places(&net);
    }
    write_file(output, &to_pnml(&net))?;
    let fused = net
        .transitions
        .iter()
        .filter(|t| t.id.contains('|'))
        .count();
    println!(
        "{} ({} fused away), {} ({fused} synchronised)",
        count(net.places.len() as u64, "place", "places"),
        before - net.places.len(),
        count(net.transitions.len() as u64, "transition", "transitions"),
    );
    println!("wrote {}", output.display());
    Ok(ExitCode::SUCCESS)
}
