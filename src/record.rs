//! `vl record`: the runs a Host recorded, as files on this machine.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::ValueHint::{DirPath, FilePath};
use vl_host::{Catalogue, RecordError, Recording};

use crate::BadInput;
use crate::report::emit;

#[derive(clap::Args)]
pub(crate) struct RecordArgs {
    #[command(subcommand)]
    command: RecordCommand,
    #[arg(long, global = true)]
    json: bool,
}

#[derive(clap::Subcommand)]
enum RecordCommand {
    /// List the runs in a recordings folder, newest first.
    Ls {
        /// The folder (default: the one `vl host` records in).
        #[arg(value_hint = DirPath)]
        dir: Option<PathBuf>,
    },
    /// What a run's file holds: its channels, its ending, whether it is whole.
    Info {
        #[arg(value_hint = FilePath)]
        file: PathBuf,
    },
    /// A run as CSV (feedback, commands), PNG frames and summary JSON.
    Export {
        #[arg(value_hint = FilePath)]
        file: PathBuf,
        /// The folder to write into.
        #[arg(long, value_hint = DirPath)]
        out: PathBuf,
    },
    /// Rewrites a file a crashed Host left unfinished as a whole one.
    Repair {
        #[arg(value_hint = FilePath)]
        file: PathBuf,
        /// Where to write (default: beside it, as NAME-repaired.mcap).
        #[arg(long, value_hint = FilePath)]
        out: Option<PathBuf>,
    },
}

fn bad(e: RecordError) -> BadInput {
    BadInput(e.to_string())
}

pub(crate) fn record(args: RecordArgs) -> Result<ExitCode> {
    let json = args.json;
    match args.command {
        RecordCommand::Ls { dir } => {
            emit(&Catalogue::at(dir.as_deref()).map_err(bad)?.runs(), json)?;
        }
        RecordCommand::Info { file } => {
            emit(&Recording::open(&file).map_err(bad)?.info(), json)?;
        }
        RecordCommand::Export { file, out } => {
            let recording = Recording::open(&file).map_err(bad)?;
            let mut exported = vl_host::export(&recording, &out).map_err(bad)?;
            let plots = vl_guest::Replay::open(&file)
                .map_err(bad)?
                .results
                .save(&out)?;
            exported.plots = plots.iter().map(|p| p.display().to_string()).collect();
            emit(&exported, json)?;
        }
        RecordCommand::Repair { file, out } => {
            emit(&vl_host::repair(&file, out.as_deref()).map_err(bad)?, json)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
