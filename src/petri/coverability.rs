//! `vl petri coverability`: the Karp–Miller tree, for nets that may be
//! unbounded.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use vl_petri::{CoverabilityError, CoverabilityReport, coverability, graph_to_dot};

use crate::BadInput;
use crate::report::emit;

use super::io::{load, write_file};

/// `vl petri coverability`.
pub(super) fn coverability_command(
    path: &Path,
    json: bool,
    dot: Option<&Path>,
    max_nodes: usize,
) -> Result<ExitCode> {
    let net = load(path)?;
    let c = coverability(&net, max_nodes).map_err(|e| match e {
        CoverabilityError::TooLarge(_) => anyhow::anyhow!("{}: {e}", path.display()),
        refused => BadInput(format!("{}: {refused}", path.display())).into(),
    })?;
    if let Some(file) = dot {
        let picture = graph_to_dot(
            &net,
            &format!("coverability of {}", net.id),
            &c.nodes,
            &c.edges,
        );
        write_file(file, &picture)?;
    }
    emit(&CoverabilityReport::of(&net, &c), json)?;
    Ok(ExitCode::SUCCESS)
}
