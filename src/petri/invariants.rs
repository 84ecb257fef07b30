//! `vl petri invariants`: the minimal P- and T-invariants.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use vl_petri::{InvariantsReport, TooManyInvariants, p_invariants, t_invariants};

use crate::report::emit;

use super::io::load;

/// `vl petri invariants`: each invariant as element id → weight.
pub(super) fn invariants_command(path: &Path, json: bool, max_rows: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let describe = |e: TooManyInvariants| {
        anyhow::anyhow!("{}: {e}; raise --max-rows to go on", path.display())
    };
    let p = p_invariants(&net, max_rows).map_err(describe)?;
    let t = t_invariants(&net, max_rows).map_err(describe)?;
    emit(&InvariantsReport::of(&net, &p, &t), json)?;
    Ok(ExitCode::SUCCESS)
}
