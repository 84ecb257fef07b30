//! `vl experiment`: the lab's experiments run headless and measured (thesis
//! ch. 7), by `vl_campaign`; this parses what to run and prints
//! how it went.

mod matrix;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use vl_campaign::{RunSeries, RunSpec};
use vl_client::Pacing;
use vl_core::{Arena, ExperimentId};

use crate::input::{SceneArgs, load_arena, seconds};
use crate::named;
use crate::named::{ExperimentChoice, ExperimentChoiceParser, ExperimentParser, offered};
use crate::report::emit;

#[derive(Subcommand)]
pub(crate) enum ExperimentCommand {
    /// Run an experiment on the simulated lab, headless, and report how it went.
    Run(Box<RunArgs>),
    /// Run every link profile × event/time pacing × seeds for both
    /// experiments and write report.md, report.json and plots.
    Report(matrix::ReportArgs),
}

#[derive(Args)]
pub(crate) struct RunArgs {
    /// The experiment, by id: in navigation the Host follows a path planned
    /// on the camera's map (thesis ch. 5); in teleoperation a scripted
    /// operator steers toward waypoints along it from the feedback it sees
    /// (thesis ch. 6); a folder's (--experiments) as its run declares.
    #[arg(value_parser = ExperimentParser::AnyId)]
    experiment: ExperimentId,
    /// Experiment folders (or folders of them) the simulated Host serves
    /// beside the shipped ones, comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = ExperimentChoiceParser, value_hint = clap::ValueHint::DirPath)]
    experiments: Vec<ExperimentChoice>,
    /// Arenas, comma-separated: shipped names or JSON files; `all` for
    /// every shipped one.
    #[arg(long, value_delimiter = ',', default_value = "navigation")]
    arena: Vec<String>,
    /// The first run's seed; run k has seed + k (the lab's and the link's).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Runs per arena.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1000))]
    runs: u64,
    /// Put the Media between Guest and Host with this link: a profile
    /// (lan, internet2, internet-2005, intercontinental, congested,
    /// geo-satellite) or a JSON file of a link model. Without it the Guest
    /// talks to the Host straight over loopback.
    #[arg(long)]
    profile: Option<String>,
    /// How the scripted operator paces its commands (teleoperation): event
    /// (command s + 1 only after the feedback for s) or time (every 20 ms).
    #[arg(long, visible_alias = "control", value_parser = named::<Pacing>(), default_value = "event")]
    pacing: Pacing,
    #[command(flatten)]
    optics: crate::options::OpticsArgs,
    /// Fold camera sightings in when they arrive, not when their frames
    /// were taken: to measure what latency compensation is worth.
    #[arg(long)]
    no_latency_compensation: bool,
    #[command(flatten)]
    frames: crate::options::FrameArgs,
    #[command(flatten)]
    scene: SceneArgs,
    /// Write a picture of each run (planned, estimated and true paths) here.
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Give up on a run after this many seconds.
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(
    runtime: &tokio::runtime::Runtime,
    command: ExperimentCommand,
) -> Result<ExitCode> {
    let args = match command {
        ExperimentCommand::Run(args) => *args,
        ExperimentCommand::Report(args) => return matrix::report(runtime, args),
    };
    let timeout = seconds("--timeout", args.timeout)?;
    let names: Vec<String> = if args.arena.iter().any(|a| a == "all") {
        Arena::shipped().map(str::to_owned).collect()
    } else {
        args.arena.clone()
    };
    let arenas = names
        .iter()
        .map(|name| load_arena(name))
        .collect::<Result<Vec<Arena>>>()?;
    let link = match &args.profile {
        Some(spec) => Some((spec.clone(), crate::media::load(spec)?)),
        None => None,
    };
    if let Some(dir) = &args.svg {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let lab = offered(&args.experiments)?;
    if let Err(unknown) = lab.get(args.experiment.as_str()) {
        return Err(crate::BadInput(unknown.to_string()).into());
    }
    let template = RunSpec {
        experiment: args.experiment.clone(),
        lab,
        arena: Arena::navigation(),
        seed: args.seed,
        optics: args
            .optics
            .optics(args.seed)
            .map_err(|e| crate::BadInput(e.to_string()))?,
        compensate_latency: !args.no_latency_compensation,
        frames: args.frames.policy(),
        scene: args.scene.events.clone(),
        link,
        pacing: args.pacing,
        timeout,
        progress: false,
    };
    let svg = args.svg.as_deref();
    let report = runtime.block_on(RunSeries::run(
        &template, &arenas, args.runs, svg, !args.json,
    ))?;
    emit(&report, args.json)?;
    Ok(if report.all_succeeded {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
