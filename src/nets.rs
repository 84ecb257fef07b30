//! `vl lab nets`: the labs' statecharts through the thesis's pipeline to
//! the controlled nets the Host runs, written (or checked) under
//! `docs/nets/<lab>/`.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};

use anyhow::{Context, Result};
use clap::Subcommand;
use vl_core::{Designed, LabDesign, NetsReport};

use crate::BadInput;
use crate::report::emit;

#[derive(Subcommand)]
pub(crate) enum LabCommand {
    /// Statecharts → nets → composition → controllers → analysis, per lab:
    /// PNML, DOT (SVG when Graphviz is installed) and a report.
    Nets {
        /// Where each lab's folder is written.
        #[arg(long, default_value = "docs/nets")]
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
    .map_err(|e| BadInput(e.to_string()))?;
    let pictures = !check && graphviz();
    let mut labs = Vec::new();
    for lab in &designs {
        let designed = vl_core::design(lab).map_err(|e| BadInput(e.to_string()))?;
        let dir = out.join(lab.lab);
        let files = if check {
            designed.differing(&dir)
        } else {
            write(&designed, &dir, pictures)?
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

/// Writes the lab's files into `dir`, and SVG pictures of its nets when
/// `pictures`; the names written.
fn write(d: &Designed, dir: &Path, pictures: bool) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut written = Vec::new();
    for (name, text) in d.files() {
        let path = dir.join(&name);
        std::fs::write(&path, &text).with_context(|| format!("cannot write {}", path.display()))?;
        if pictures && let Some(stem) = name.strip_suffix(".dot") {
            let svg = dir.join(format!("{stem}.svg"));
            render(&path, &svg)?;
            written.push(format!("{stem}.svg"));
        }
        written.push(name);
    }
    Ok(written)
}

fn graphviz() -> bool {
    Command::new("dot")
        .arg("-V")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn render(dot: &Path, svg: &Path) -> Result<()> {
    let status = Command::new("dot")
        .arg("-Tsvg")
        .arg(dot)
        .arg("-o")
        .arg(svg)
        .status()
        .context("cannot run Graphviz's dot")?;
    anyhow::ensure!(status.success(), "dot failed on {}", dot.display());
    Ok(())
}
