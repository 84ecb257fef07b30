//! `vl lab nets`: the labs' statecharts through the thesis's pipeline to
//! the controlled nets the Host runs, written (or checked) under
//! `docs/nets/<lab>/`.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};

use anyhow::{Context, Result};
use clap::Subcommand;
use serde::Serialize;
use vl_core::{Designed, LabDesign, Named};

use crate::BadInput;
use crate::report::{Report, Table, emit};

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

/// One lab's outcome, as the table and `--json` show it.
#[derive(Serialize)]
struct LabRow {
    lab: &'static str,
    charts: usize,
    /// Rules the uncontrolled composition can break.
    broken_without: usize,
    rules: usize,
    places: usize,
    transitions: usize,
    markings: usize,
    bounded: bool,
    safe: bool,
    live: bool,
    reversible: bool,
    deadlock_free: bool,
    /// Rules the controlled net can still break.
    broken_with: usize,
    /// Files written, or (with --check) found different.
    files: Vec<String>,
}

#[derive(Serialize)]
struct NetsReport {
    out: PathBuf,
    check: bool,
    pictures: bool,
    labs: Vec<LabRow>,
}

impl Report for NetsReport {
    fn table(&self) -> Table {
        let yes = |b: bool| if b { "yes" } else { "NO" }.to_owned();
        let mut table = Table::columns(&[
            "lab",
            "charts",
            "broken without",
            "places",
            "transitions",
            "markings",
            "bounded",
            "safe",
            "live",
            "reversible",
            "deadlock-free",
            "broken with",
        ]);
        for l in &self.labs {
            table.row(vec![
                l.lab.to_owned(),
                l.charts.to_string(),
                format!("{} of {}", l.broken_without, l.rules),
                l.places.to_string(),
                l.transitions.to_string(),
                l.markings.to_string(),
                yes(l.bounded),
                yes(l.safe),
                yes(l.live),
                yes(l.reversible),
                yes(l.deadlock_free),
                format!("{} of {}", l.broken_with, l.rules),
            ]);
        }
        let mut table = table.title(
            "each lab's controlled net, and the rules broken without and with its controllers:",
        );
        for l in &self.labs {
            let dir = self.out.join(l.lab);
            table = table.note(if self.check {
                match l.files.is_empty() {
                    true => format!("{}: up to date", dir.display()),
                    false => format!("{}: differs in {}", dir.display(), l.files.join(", ")),
                }
            } else {
                format!("{}: wrote {}", dir.display(), l.files.join(", "))
            });
        }
        if !self.check && !self.pictures {
            table = table.note("Graphviz's `dot` is not installed: no SVG pictures");
        }
        table
    }
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
        let dir = out.join(lab.lab.id());
        let files = if check {
            differing(&designed, &dir)
        } else {
            write(&designed, &dir, pictures)?
        };
        labs.push(row(&designed, files));
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

fn row(d: &Designed, files: Vec<String>) -> LabRow {
    let a = &d.controlled_analysis;
    let count = |v: &[(vl_core::Rule, Option<vl_core::Interleaving>)]| {
        v.iter().filter(|(_, bad)| bad.is_some()).count()
    };
    LabRow {
        lab: d.design.lab.id(),
        charts: d.design.charts.len(),
        broken_without: count(&d.bad),
        rules: d.bad.len(),
        places: a.places,
        transitions: a.transitions,
        markings: a.states,
        bounded: a.bounded,
        safe: a.safe,
        live: a.live,
        reversible: a.reversible,
        deadlock_free: !a.deadlock,
        broken_with: count(&d.still_bad),
        files,
    }
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

/// The lab's files that are missing from `dir` or differ from what the
/// pipeline makes now.
fn differing(d: &Designed, dir: &Path) -> Vec<String> {
    d.files()
        .into_iter()
        .filter(|(name, text)| std::fs::read_to_string(dir.join(name)).ok().as_ref() != Some(text))
        .map(|(name, _)| name)
        .collect()
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
