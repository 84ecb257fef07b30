//! `vl lab nets`: the labs' statecharts through the thesis's pipeline to
//! the controlled nets the Host runs, written (or checked) beside each
//! lab's charts, `crates/vl-core/nets/<lab>/`, where the Host builds them in.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use vl_core::{LabDesign, NetsReport};

use crate::bad_input;
use crate::report::emit;

#[derive(Subcommand)]
pub(crate) enum LabCommand {
    /// Statecharts → nets → composition → controllers → analysis, per lab:
    /// PNML, DOT (SVG when Graphviz is installed) and a report.
    Nets {
        /// Where each lab's folder is written (in a clone of vl: beside the
        /// charts, which is where the Host's built-in nets come from).
        #[arg(long, default_value = "crates/vl-core/nets")]
        out: PathBuf,
        /// The charts' folder (laid out as crates/vl-core/nets/); the
        /// shipped charts when not given.
        #[arg(long)]
        charts: Option<PathBuf>,
        /// Compare with what is in --out instead of writing; fail on a difference.
        #[arg(long)]
        check: bool,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) fn run(command: LabCommand) -> Result<ExitCode> {
    let LabCommand::Nets {
        out,
        charts,
        check,
        json,
    } = command;
    let designs = match &charts {
        Some(dir) => LabDesign::load(dir),
        None => LabDesign::shipped(),
    }
    .map_err(bad_input)?;
    let pictures = !check && vl_petri::graphviz_available();
    let mut labs = Vec::new();
    for lab in &designs {
        let designed = vl_core::design(lab).map_err(bad_input)?;
        let dir = out.join(lab.lab);
        let files = if check {
            designed.differing(&dir)
        } else {
            designed.write(&dir, pictures)?
        };
        labs.push(designed.summary(files));
    }
    let failed = labs
        .iter()
        .any(|l| l.broken_with > 0 || (check && !l.files.is_empty()));
    emit(
        &NetsReport {
            out,
            check,
            pictures,
            labs,
        },
        json,
    )?;
    Ok(if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}
