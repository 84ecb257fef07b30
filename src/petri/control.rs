//! `vl petri control`: controllers synthesised for constraints.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use vl_petri::{Added, Constraint, ControlError, Limits, synthesize, to_pnml};

use crate::BadInput;

use super::io::{load, write_file};

pub(super) fn control_command(
    path: &Path,
    constraints: &[String],
    uncontrollable: Vec<String>,
    unobservable: Vec<String>,
    output: &Path,
) -> Result<ExitCode> {
    let plant = load(path)?;
    let bad = |e: ControlError| BadInput(format!("{}: {e}", path.display()));
    let constraints = constraints
        .iter()
        .map(|c| Constraint::parse(c))
        .collect::<Result<Vec<_>, _>>()
        .map_err(bad)?;
    let limits = Limits {
        uncontrollable,
        unobservable,
    };
    let (net, added) = synthesize(&plant, &constraints, &limits).map_err(bad)?;
    write_file(output, &to_pnml(&net))?;
    for a in &added {
        match a {
            Added::Monitor {
                place,
                initial,
                enforced,
            } => {
                println!("monitor place {place:<12} m0 = {initial:<4} enforces {enforced}")
            }
            Added::Inhibitor { place, transition } => {
                println!("inhibitor arc {place} ⊸ {transition}")
            }
        }
    }
    println!("wrote {}", output.display());
    Ok(ExitCode::SUCCESS)
}
