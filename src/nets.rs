//! `vl lab nets`: the labs' statecharts through the thesis's pipeline to
//! the controlled nets the Host runs, written (or checked) beside each
//! lab's charts, `crates/vl-core/nets/<lab>/`, where the Host builds them in.
//! `vl lab check`: an experiment folder through the same pipeline, verified.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Subcommand;
use vl_core::{CheckReport, FolderCheck, LabDesign, NetsReport};

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
        /// A folder of designs: experiment folders (each an
        /// experiment.toml beside its charts), and the access design
        /// (access/lab.toml) and shared charts (common/) where they differ
        /// from the shipped ones; everything shipped when not given.
        #[arg(long)]
        charts: Option<PathBuf>,
        /// Compare with what is in --out instead of writing; fail on a difference.
        #[arg(long)]
        check: bool,
        #[arg(long)]
        json: bool,
    },
    /// Design and verify experiment folders, saying what is wrong with each.
    ///
    /// Each folder (an experiment.toml beside its charts) is composed with
    /// the shared charts, given its controllers, and checked bounded, safe,
    /// free of dead ends, able to return to its start, every rule kept. A
    /// refusal names the file and the line, or the firing sequence.
    Check {
        /// The experiment folders.
        #[arg(required = true, value_hint = clap::ValueHint::DirPath)]
        folders: Vec<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Make a new experiment folder ID in DIR, from the first shipped
    /// experiment's charts and controllers: it passes `vl lab check` as made.
    New {
        /// The experiment's id: a lowercase word (`-` and `_` allowed).
        id: String,
        /// Where the folder is made.
        #[arg(long, default_value = ".", value_hint = clap::ValueHint::DirPath)]
        dir: PathBuf,
    },
}

pub(crate) fn run(command: LabCommand) -> Result<ExitCode> {
    let (out, charts, check, json) = match command {
        LabCommand::Nets {
            out,
            charts,
            check,
            json,
        } => (out, charts, check, json),
        LabCommand::Check { folders, json } => return check_folders(&folders, json),
        LabCommand::New { id, dir } => return new_folder(&id, &dir),
    };
    let designs = match &charts {
        Some(dir) => LabDesign::load(dir),
        None => LabDesign::shipped(),
    }
    .map_err(bad_input)?;
    let pictures = !check && vl_petri::graphviz_available();
    let mut labs = Vec::new();
    for lab in &designs {
        let designed = vl_core::design(lab).map_err(bad_input)?;
        let dir = out.join(&lab.lab);
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

/// `vl lab check`: every folder's verdict; fails if any is refused or fails.
fn check_folders(folders: &[PathBuf], json: bool) -> Result<ExitCode> {
    let report = CheckReport {
        folders: folders.iter().map(|f| FolderCheck::of(f)).collect(),
    };
    emit(&report, json)?;
    Ok(if report.folders.iter().all(FolderCheck::passed) {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// `vl lab new`: the folder, written only where nothing is yet.
fn new_folder(id: &str, dir: &Path) -> Result<ExitCode> {
    let files = LabDesign::scaffold(id).map_err(bad_input)?;
    let folder = dir.join(id);
    if folder.exists() {
        return Err(bad_input(format!(
            "{} is there already: give another id or --dir",
            folder.display()
        ))
        .into());
    }
    std::fs::create_dir_all(&folder)
        .with_context(|| format!("cannot make {}", folder.display()))?;
    for (name, text) in &files {
        let file = folder.join(name);
        std::fs::write(&file, text).with_context(|| format!("cannot write {}", file.display()))?;
    }
    let names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
    println!("made {}: {}", folder.display(), names.join(", "));
    println!("check it with: vl lab check {}", folder.display());
    Ok(ExitCode::SUCCESS)
}
