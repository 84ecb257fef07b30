//! `vl vision …`: what the overhead camera's frames tell, for calibrating
//! the lab and checking the vision pipeline.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use vl_core::{Threshold, inspect};

use crate::input::load_rgb;
use crate::report::emit;

#[derive(Subcommand)]
pub(crate) enum VisionCommand {
    /// Threshold a frame, list its connected components (8-connected) with
    /// their moments, and find the robot by its markers.
    Inspect {
        image: PathBuf,
        /// otsu, or a grey level 0–255: foreground is brighter than it.
        #[arg(long, default_value = "otsu")]
        threshold: Threshold,
        /// Foreground is darker instead (dark objects on a light floor).
        #[arg(long)]
        invert: bool,
        #[arg(long)]
        json: bool,
    },
    /// Time the whole pipeline on one frame, in-process, over many runs.
    Bench {
        image: PathBuf,
        #[arg(long, default_value_t = 200)]
        runs: u32,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) fn run(command: VisionCommand) -> Result<ExitCode> {
    match command {
        VisionCommand::Inspect {
            image,
            threshold,
            invert,
            json,
        } => emit(
            &inspect(&load_rgb(&image, "image")?, threshold, invert),
            json,
        )?,
        VisionCommand::Bench { image, runs, json } => emit(
            &vl_core::bench_vision(&load_rgb(&image, "image")?, runs),
            json,
        )?,
    }
    Ok(ExitCode::SUCCESS)
}
