//! `vl experiment`: the lab's experiments run headless and measured (thesis
//! ch. 7). Each run is a simulated Host on loopback and a Guest against it
//! over a real socket: mount, map from the camera, plan, define, follow.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use serde::Serialize;
use vl_core::{ARENA_CELL_MM, Arena, ErrorMm, Experiment, PoseSource, run_svg};
use vl_guest::{Report as RunReport, Script};
use vl_host::{Host, HostConfig, SimCamera, SimLab};

use crate::BadInput;
use crate::lab::{FramesArgs, SceneArgs};
use crate::report::{Report, Table, count, emit, yes};
use crate::sim::{OpticsArgs, load_arena};

#[derive(Subcommand)]
pub(crate) enum ExperimentCommand {
    /// Run an experiment on the simulated lab, headless, and report how it went.
    Run(RunArgs),
}

/// The experiments `vl experiment run` knows.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Which {
    /// Navigation (thesis ch. 5): the Host follows a path planned on the
    /// camera's map, steering from camera-based estimates.
    Mobile,
}

#[derive(Args)]
pub(crate) struct RunArgs {
    #[arg(value_enum)]
    which: Which,
    /// Arenas, comma-separated: shipped names or JSON files; `all` for
    /// every shipped one.
    #[arg(long, value_delimiter = ',', default_value = "navigation")]
    arena: Vec<String>,
    /// The first run's seed; run k has seed + k.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Runs per arena.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1000))]
    runs: u64,
    #[command(flatten)]
    optics: OpticsArgs,
    #[command(flatten)]
    frames: FramesArgs,
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

/// One run, as `--json` gives it.
#[derive(Serialize)]
struct Run {
    arena: String,
    seed: u64,
    reached_goal: bool,
    end: String,
    pose_source: PoseSource,
    path_error_mm: Option<ErrorMm>,
    estimate_error_mm: Option<ErrorMm>,
    collisions: u64,
    video_bytes: u64,
    frames_sent: u64,
    seconds: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    svg: Option<PathBuf>,
}

#[derive(Serialize)]
struct Runs {
    runs: Vec<Run>,
    /// Every run reached its goal without touching anything.
    all_succeeded: bool,
    /// Over all runs: the mean of their mean path errors, and the largest.
    path_error_mm: Option<ErrorMm>,
    estimate_error_mm: Option<ErrorMm>,
}

fn mm(e: Option<ErrorMm>, pick: fn(&ErrorMm) -> f64) -> String {
    e.map_or("–".into(), |e| format!("{:.1}", pick(&e)))
}

impl Report for Runs {
    fn table(&self) -> Table {
        let mut table = Table::columns(&[
            "arena",
            "seed",
            "goal",
            "collisions",
            "path mean",
            "path max",
            "path rms",
            "estimate mean",
            "estimate max",
            "seconds",
            "frames",
            "video kB",
        ]);
        for run in &self.runs {
            table.row(vec![
                run.arena.clone(),
                run.seed.to_string(),
                yes(run.reached_goal).into(),
                run.collisions.to_string(),
                mm(run.path_error_mm, |e| e.mean),
                mm(run.path_error_mm, |e| e.max),
                mm(run.path_error_mm, |e| e.rms),
                mm(run.estimate_error_mm, |e| e.mean),
                mm(run.estimate_error_mm, |e| e.max),
                format!("{:.2}", run.seconds),
                run.frames_sent.to_string(),
                format!("{:.0}", run.video_bytes as f64 / 1e3),
            ]);
        }
        let failed = self.runs.iter().filter(|r| !succeeded(r)).count();
        let mut table = table.title("errors in mm; the path error is the true pose's distance to the planned path, the estimate error the estimate's to the true pose");
        table = table.note(format!(
            "{}; {} failed; path error over all: {}",
            count(self.runs.len() as u64, "run", "runs"),
            failed,
            crate::lab::error_mm(self.path_error_mm)
        ));
        table
    }
}

fn succeeded(run: &Run) -> bool {
    run.reached_goal && run.collisions == 0
}

pub(crate) fn run(
    runtime: &tokio::runtime::Runtime,
    command: ExperimentCommand,
) -> Result<ExitCode> {
    let ExperimentCommand::Run(args) = command;
    let Which::Mobile = args.which;
    if !(args.timeout.is_finite() && args.timeout > 0.0) {
        return Err(BadInput(format!(
            "--timeout must be a positive number of seconds, not {}",
            args.timeout
        ))
        .into());
    }
    let names: Vec<String> = if args.arena.iter().any(|a| a == "all") {
        Arena::shipped().map(str::to_owned).collect()
    } else {
        args.arena.clone()
    };
    let arenas = names
        .iter()
        .map(|name| load_arena(name))
        .collect::<Result<Vec<Arena>>>()?;
    if let Some(dir) = &args.svg {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let total = arenas.len() as u64 * args.runs;
    let mut runs = Vec::new();
    for arena in &arenas {
        for k in 0..args.runs {
            let seed = args.seed + k;
            let optics = args.optics.optics(seed)?;
            let lab = SimLab {
                seed,
                camera: Some(SimCamera {
                    optics,
                    calibration: None,
                }),
                scene: args.scene.events.clone(),
                ..SimLab::new(arena.clone())
            };
            let config = HostConfig {
                frames: args.frames.policy()?,
                ..HostConfig::default()
            };
            let report = runtime.block_on(async {
                let host = Host::start_sim(([127, 0, 0, 1], 0).into(), lab, config)
                    .await
                    .context("cannot start the simulated Host")?;
                let script = Script {
                    experiment: Experiment::Navigation,
                    timeout: Duration::from_secs_f64(args.timeout),
                    ..Script::default()
                };
                vl_guest::drive_to_goal(&host.url(), &script)
                    .await
                    .with_context(|| format!("the run on {} with seed {seed}", arena.name))
            })?;
            let svg = match &args.svg {
                Some(dir) => Some(picture(dir, arena, seed, &report)?),
                None => None,
            };
            let run = record(arena, seed, report, svg);
            if !args.json {
                let strayed = run.path_error_mm.map_or(String::new(), |e| {
                    format!(
                        ", {:.1} mm from the planned path on average, {:.1} at most",
                        e.mean, e.max
                    )
                });
                let outcome = if run.reached_goal {
                    "reached the goal"
                } else {
                    "did not reach the goal"
                };
                eprintln!(
                    "[{}/{total}] {} seed {seed}: {outcome} in {:.1} s, {}{strayed}",
                    runs.len() + 1,
                    run.arena,
                    run.seconds,
                    count(run.collisions, "collision", "collisions"),
                );
            }
            runs.push(run);
        }
    }
    let overall = |pick: fn(&Run) -> Option<ErrorMm>| {
        let all: Vec<ErrorMm> = runs.iter().filter_map(pick).collect();
        (!all.is_empty()).then(|| ErrorMm {
            mean: all.iter().map(|e| e.mean).sum::<f64>() / all.len() as f64,
            max: all.iter().map(|e| e.max).fold(0.0, f64::max),
            rms: (all.iter().map(|e| e.rms * e.rms).sum::<f64>() / all.len() as f64).sqrt(),
        })
    };
    let report = Runs {
        path_error_mm: overall(|r| r.path_error_mm),
        estimate_error_mm: overall(|r| r.estimate_error_mm),
        all_succeeded: runs.iter().all(succeeded),
        runs,
    };
    emit(&report, args.json)?;
    Ok(if report.all_succeeded {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn record(arena: &Arena, seed: u64, report: RunReport, svg: Option<PathBuf>) -> Run {
    let path = report.path.as_ref();
    Run {
        arena: arena.name.clone(),
        seed,
        reached_goal: report.reached_goal,
        end: report.reason.to_string(),
        pose_source: report.pose_source,
        path_error_mm: path.and_then(|p| p.path_error_mm),
        estimate_error_mm: path.and_then(|p| p.estimate_error_mm),
        collisions: report.collisions,
        video_bytes: report.video_bytes,
        frames_sent: report.frames,
        seconds: report.sim_seconds,
        svg,
    }
}

/// Writes the run's picture into `dir`, named by arena and seed.
fn picture(dir: &std::path::Path, arena: &Arena, seed: u64, report: &RunReport) -> Result<PathBuf> {
    let file = dir.join(format!("{}-seed{seed}.svg", arena.name));
    let Some(path) = &report.path else {
        return Ok(file);
    };
    let svg = run_svg(arena, ARENA_CELL_MM, &report.planned, path)
        .map_err(|e| BadInput(format!("cannot draw arena {}: {e}", arena.name)))?;
    std::fs::write(&file, svg).with_context(|| format!("cannot write {}", file.display()))?;
    Ok(file)
}
