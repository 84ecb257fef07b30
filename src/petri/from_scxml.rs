//! `vl petri from-scxml`: a UML statechart as a net.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use vl_petri::{from_scxml, to_pnml};

use crate::BadInput;
use crate::report::count;
use crate::shipped::read_input;

use super::io::write_file;

pub(super) fn from_scxml_command(path: &Path, output: &Path) -> Result<ExitCode> {
    let text = read_input(path)?;
    let net = from_scxml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
    write_file(output, &to_pnml(&net))?;
    println!(
        "{} (states), {}; wrote {}",
        count(net.places.len() as u64, "place", "places"),
        count(net.transitions.len() as u64, "transition", "transitions"),
        output.display()
    );
    Ok(ExitCode::SUCCESS)
}
