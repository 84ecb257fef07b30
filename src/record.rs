//! `vl record`: the runs a Host recorded, as files on this machine.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::ValueHint::{DirPath, FilePath};
#[cfg(feature = "host")]
use vl_record::RecordSettings;
use vl_record::{Catalogue, RecordError, Recording};

use crate::BadInput;
use crate::report::emit;

/// Where and how long `vl host` keeps its runs.
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub(crate) struct KeepArgs {
    /// Where every run is recorded, as MCAP files Foxglove opens (default:
    /// vl/recordings in the user's data directory).
    #[arg(long, value_hint = DirPath)]
    recordings: Option<PathBuf>,
    /// Record nothing.
    #[arg(long, conflicts_with = "recordings")]
    no_record: bool,
    /// Delete recordings older than this many days, oldest first.
    #[arg(long, value_parser = positive)]
    keep_days: Option<f64>,
    /// Keep at most this many GB of recordings, the file being written
    /// among them: the oldest go first, then the run's own recording stops.
    #[arg(long, value_parser = positive)]
    keep_gb: Option<f64>,
    /// Record the time between runs too (files idle-*.mcap, for
    /// administrators), not only the runs.
    #[arg(long)]
    record_idle: bool,
}

impl KeepArgs {
    #[cfg(feature = "host")]
    pub(crate) fn settings(&self) -> RecordSettings {
        RecordSettings {
            recordings: self.recordings.clone(),
            no_record: self.no_record,
            keep_days: self.keep_days,
            keep_gb: self.keep_gb,
            record_idle: self.record_idle,
        }
    }
}

fn positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("\"{text}\" is not a positive number")),
    }
}

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
    /// Grades a run again by its experiment's rubric; a run a user's
    /// controller drove is also run again on the lab's twin, with exactly
    /// the module the file keeps.
    Regrade {
        #[arg(value_hint = FilePath)]
        file: PathBuf,
        /// Seeds of the twin's noise to rerun the controller with (1 to 8).
        #[arg(long, default_value_t = vl_sim::FORECAST_SEEDS.len() as u32,
              value_parser = clap::value_parser!(u32).range(1..=8))]
        seeds: u32,
        /// Experiment folders, for a run of one vl does not ship.
        #[arg(long, value_hint = DirPath)]
        experiments: Vec<PathBuf>,
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
            let mut exported = vl_record::export(&recording, &out).map_err(bad)?;
            let plots = vl_client::Replay::open(&file)
                .map_err(bad)?
                .results
                .save(&out)?;
            exported.plots = plots.iter().map(|p| p.display().to_string()).collect();
            emit(&exported, json)?;
        }
        RecordCommand::Repair { file, out } => {
            emit(
                &vl_record::repair(&file, out.as_deref()).map_err(bad)?,
                json,
            )?;
        }
        RecordCommand::Regrade {
            file,
            seeds,
            experiments,
        } => {
            let regraded = crate::regrade::regrade(&crate::regrade::Regrading {
                file: &file,
                seeds,
                folders: &experiments,
            })?;
            emit(&regraded, json)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
