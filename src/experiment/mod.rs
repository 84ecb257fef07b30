//! `vl experiment`: the lab's experiments run headless and measured (thesis
//! ch. 7). Each run is a simulated Host on loopback, optionally behind the
//! Media (a relay with a modelled Internet link), and a Guest against it
//! over real sockets: mount, map from the camera, plan, define, then the
//! Host follows the path (`navigation`) or a scripted operator steers along
//! it from the delayed feedback (`teleoperation`). `vl experiment report` runs the
//! whole matrix of links and control modes and writes a report with plots.

mod matrix;
mod plots;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use serde::Serialize;
use vl_core::{ARENA_CELL_MM, Arena, ErrorMm, Experiment, PoseSource, run_svg};
use vl_guest::{ControlMode, Report as RunReport, RoundTripMs, Script, Spread, TIME_PERIOD};
use vl_host::{Host, HostConfig, Media, MediaConfig, SimCamera, SimLab};
use vl_sim::{LinkModel, Optics, Scheduled};

use crate::BadInput;
use crate::input::{FramesArgs, OpticsArgs, SceneArgs, load_arena, seconds};
use crate::report::{Report, Table, count, emit, yes};

#[derive(Subcommand)]
pub(crate) enum ExperimentCommand {
    /// Run an experiment on the simulated lab, headless, and report how it went.
    Run(Box<RunArgs>),
    /// Run every link profile × event/time control × seeds for both
    /// experiments and write report.md, report.json and plots.
    Report(matrix::ReportArgs),
}

/// How the operator's commands are paced.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum, Serialize, Debug)]
#[serde(rename_all = "lowercase")]
pub(crate) enum Control {
    /// Command s + 1 only after the feedback for s (thesis §3.5).
    Event,
    /// A command every 20 ms, whatever has come back.
    Time,
}

impl Control {
    fn mode(self) -> ControlMode {
        match self {
            Control::Event => ControlMode::Event,
            Control::Time => ControlMode::Time {
                period: TIME_PERIOD,
            },
        }
    }
}

#[derive(Args)]
pub(crate) struct RunArgs {
    /// navigation: the Host follows a path planned on the camera's map
    /// (thesis ch. 5); teleoperation: a scripted operator steers toward
    /// waypoints along it from the feedback it sees (thesis ch. 6).
    #[arg(value_parser = crate::named::<Experiment>())]
    experiment: Experiment,
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
    /// How the operator paces commands (teleoperation).
    #[arg(long, value_enum, default_value = "event")]
    control: Control,
    #[command(flatten)]
    optics: OpticsArgs,
    /// Fold camera sightings in when they arrive, not when their frames
    /// were taken: to measure what latency compensation is worth.
    #[arg(long)]
    no_latency_compensation: bool,
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

/// Percentiles of one leg's one-way delay, ms.
#[derive(Serialize, Clone, Copy, Debug)]
pub(crate) struct Leg {
    pub messages: usize,
    pub p50: f64,
    pub p90: f64,
    pub p99: f64,
    pub max: f64,
}

impl Leg {
    fn of(ms: &[f64]) -> Option<Leg> {
        if ms.is_empty() {
            return None;
        }
        let mut sorted = ms.to_vec();
        sorted.sort_by(f64::total_cmp);
        let at = |q: f64| vl_core::nearest_rank(&sorted, q).unwrap_or(f64::NAN);
        Some(Leg {
            messages: sorted.len(),
            p50: at(0.5),
            p90: at(0.9),
            p99: at(0.99),
            max: at(1.0),
        })
    }
}

/// The one-way delays each leg saw, measured at the Media.
#[derive(Serialize, Clone, Debug)]
pub(crate) struct Legs {
    pub guest_to_host: Option<Leg>,
    pub host_to_guest: Option<Leg>,
    /// Camera frames: from leaving the Host to reaching the Guest.
    pub frames_to_guest: Option<Leg>,
    /// Every delay, for the report's histograms (not in --json).
    #[serde(skip)]
    pub samples: vl_host::Delays,
}

/// One run, as `--json` gives it.
#[derive(Serialize, Clone, Debug)]
pub(crate) struct Run {
    pub experiment: Experiment,
    pub arena: String,
    pub seed: u64,
    /// The link between Guest and Host; none for straight loopback.
    pub profile: Option<String>,
    pub control: Control,
    pub reached_goal: bool,
    pub end: String,
    pub pose_source: PoseSource,
    pub collisions: u64,
    /// Commands the operator sent, the largest gap between a command and
    /// the feedback it was sent on, and the commands more than one ahead.
    pub commands: u64,
    pub max_event_gap: u64,
    pub sync_violations: u64,
    /// The true pose's distance to the planned path.
    pub tracking_error_mm: Option<ErrorMm>,
    /// The estimate's distance to the true pose.
    pub estimate_error_mm: Option<ErrorMm>,
    /// The run's length on the lab's clock.
    pub completion_s: f64,
    /// The predicted pose against the feedback that later arrived, and the
    /// last reported pose against it.
    pub prediction_error_mm: Spread,
    pub stale_error_mm: Spread,
    pub round_trip_ms: RoundTripMs,
    pub delays: Option<Legs>,
    pub video_bytes: u64,
    pub frames_sent: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub svg: Option<PathBuf>,
    /// The planned and the true path, for the report's pictures.
    #[serde(skip)]
    pub report: Option<RunReport>,
}

impl Run {
    pub(crate) fn succeeded(&self) -> bool {
        self.reached_goal && self.collisions == 0
    }
}

#[derive(Serialize)]
struct Runs {
    runs: Vec<Run>,
    /// Every run reached its goal without touching anything.
    all_succeeded: bool,
    /// Over all runs: the mean of their mean tracking errors, and the largest.
    tracking_error_mm: Option<ErrorMm>,
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
            "track mean",
            "track max",
            "estimate max",
            "gap",
            "sync lost",
            "predict mean",
            "stale mean",
            "seconds",
            "video kB",
        ]);
        for run in &self.runs {
            table.row(vec![
                run.arena.clone(),
                run.seed.to_string(),
                yes(run.reached_goal).into(),
                run.collisions.to_string(),
                mm(run.tracking_error_mm, |e| e.mean),
                mm(run.tracking_error_mm, |e| e.max),
                mm(run.estimate_error_mm, |e| e.max),
                run.max_event_gap.to_string(),
                run.sync_violations.to_string(),
                spread(run.prediction_error_mm),
                spread(run.stale_error_mm),
                format!("{:.2}", run.completion_s),
                format!("{:.0}", run.video_bytes as f64 / 1e3),
            ]);
        }
        let failed = self.runs.iter().filter(|r| !r.succeeded()).count();
        let mut table = table.title(
            "errors in mm; tracking: the true pose to the planned path; estimate: the \
             estimate to the true pose; gap: the largest command event ahead of the feedback \
             it was sent on; predict/stale: the predicted / last reported pose against the \
             feedback that came next",
        );
        table = table.note(format!(
            "{}; {} failed; tracking error over all: {}",
            count(self.runs.len() as u64, "run", "runs"),
            failed,
            crate::lab::error_mm(self.tracking_error_mm)
        ));
        table
    }
}

pub(crate) fn spread(s: Spread) -> String {
    if s.count == 0 {
        "–".into()
    } else {
        format!("{:.1}", s.mean)
    }
}

/// What one run is: everything `run_one` needs.
#[derive(Clone)]
pub(crate) struct RunSpec {
    pub experiment: Experiment,
    pub arena: Arena,
    pub seed: u64,
    pub optics: Optics,
    pub compensate_latency: bool,
    pub frames: vl_host::FramePolicy,
    pub scene: Vec<Scheduled>,
    /// The link's name (as given) and model; none for straight loopback.
    pub link: Option<(String, LinkModel)>,
    pub control: Control,
    pub timeout: Duration,
    pub progress: bool,
}

/// Runs one experiment: a simulated Host, the Media in front of it when a
/// link is given, and the scripted Guest through it.
pub(crate) async fn run_one(spec: &RunSpec) -> Result<Run> {
    let lab = SimLab {
        seed: spec.seed,
        camera: Some(SimCamera {
            optics: spec.optics,
            calibration: None,
        }),
        scene: spec.scene.clone(),
        ..SimLab::new(spec.arena.clone())
    };
    let config = HostConfig {
        frames: spec.frames,
        compensate_latency: spec.compensate_latency,
        ..HostConfig::default()
    };
    let host = Host::start_sim(([127, 0, 0, 1], 0).into(), lab, config)
        .await
        .context("cannot start the simulated Host")?;
    let media = match &spec.link {
        Some((_, model)) => Some(
            Media::start(
                ([127, 0, 0, 1], 0).into(),
                MediaConfig {
                    upstream: host.url(),
                    model: model.clone(),
                    seed: spec.seed,
                },
            )
            .await
            .context("cannot start the Media")?,
        ),
        None => None,
    };
    let url = media.as_ref().map_or_else(|| host.url(), Media::url);
    let script = Script {
        experiment: spec.experiment,
        timeout: spec.timeout,
        progress: spec.progress,
        control: spec.control.mode(),
        ..Script::default()
    };
    let report = match spec.experiment {
        Experiment::Navigation => vl_guest::drive_to_goal(&url, &script).await,
        Experiment::Teleoperation => vl_guest::teleoperate(&url, &script).await,
    }
    .with_context(|| format!("the run on {} with seed {}", spec.arena.name, spec.seed))?;
    let delays = media.as_ref().map(|m| {
        let samples = m.delays();
        Legs {
            guest_to_host: Leg::of(&samples.to_host),
            host_to_guest: Leg::of(&samples.to_guest),
            frames_to_guest: Leg::of(&samples.frames_to_guest),
            samples,
        }
    });
    let path = report.path.as_ref();
    Ok(Run {
        experiment: spec.experiment,
        arena: spec.arena.name.clone(),
        seed: spec.seed,
        profile: spec.link.as_ref().map(|(name, _)| name.clone()),
        control: spec.control,
        reached_goal: report.reached_goal,
        end: report.ending(),
        pose_source: report.pose_source,
        collisions: report.collisions,
        commands: report.commands,
        max_event_gap: report.max_event_gap,
        sync_violations: report.sync_violations,
        tracking_error_mm: path.and_then(|p| p.path_error_mm),
        estimate_error_mm: path.and_then(|p| p.estimate_error_mm),
        completion_s: report.sim_seconds,
        prediction_error_mm: report.prediction_error_mm,
        stale_error_mm: report.stale_error_mm,
        round_trip_ms: report.round_trip_ms,
        delays,
        video_bytes: report.video_bytes,
        frames_sent: report.frames,
        svg: None,
        report: Some(report),
    })
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
    let total = arenas.len() as u64 * args.runs;
    let mut runs = Vec::new();
    for arena in &arenas {
        for k in 0..args.runs {
            let seed = args.seed + k;
            let spec = RunSpec {
                experiment: args.experiment,
                arena: arena.clone(),
                seed,
                optics: args.optics.optics(seed)?,
                compensate_latency: !args.no_latency_compensation,
                frames: args.frames.policy()?,
                scene: args.scene.events.clone(),
                link: link.clone(),
                control: args.control,
                timeout,
                progress: false,
            };
            let mut run = runtime.block_on(run_one(&spec))?;
            if let Some(dir) = &args.svg {
                run.svg = Some(picture(dir, arena, seed, run.report.as_ref())?);
            }
            if !args.json {
                eprintln!("[{}/{total}] {}", runs.len() + 1, line(&run));
            }
            runs.push(run);
        }
    }
    let report = Runs {
        tracking_error_mm: overall(&runs, |r| r.tracking_error_mm),
        estimate_error_mm: overall(&runs, |r| r.estimate_error_mm),
        all_succeeded: runs.iter().all(Run::succeeded),
        runs,
    };
    emit(&report, args.json)?;
    Ok(if report.all_succeeded {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// A run's outcome in a line of progress.
pub(crate) fn line(run: &Run) -> String {
    let strayed = run.tracking_error_mm.map_or(String::new(), |e| {
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
    format!(
        "{} seed {}: {outcome} in {:.1} s, {}{strayed}",
        run.arena,
        run.seed,
        run.completion_s,
        count(run.collisions, "collision", "collisions"),
    )
}

/// Over `runs`: the mean of their means, the largest max, the rms of rms.
pub(crate) fn overall(runs: &[Run], pick: fn(&Run) -> Option<ErrorMm>) -> Option<ErrorMm> {
    let all: Vec<ErrorMm> = runs.iter().filter_map(pick).collect();
    (!all.is_empty()).then(|| ErrorMm {
        mean: all.iter().map(|e| e.mean).sum::<f64>() / all.len() as f64,
        max: all.iter().map(|e| e.max).fold(0.0, f64::max),
        rms: (all.iter().map(|e| e.rms * e.rms).sum::<f64>() / all.len() as f64).sqrt(),
    })
}

/// Writes the run's picture into `dir`, named by arena and seed.
fn picture(
    dir: &std::path::Path,
    arena: &Arena,
    seed: u64,
    report: Option<&RunReport>,
) -> Result<PathBuf> {
    let file = dir.join(format!("{}-seed{seed}.svg", arena.name));
    let Some((report, path)) = report.and_then(|r| r.path.as_ref().map(|p| (r, p))) else {
        return Ok(file);
    };
    let svg = run_svg(arena, ARENA_CELL_MM, &report.planned, path)
        .map_err(|e| BadInput(format!("cannot draw arena {}: {e}", arena.name)))?;
    std::fs::write(&file, svg).with_context(|| format!("cannot write {}", file.display()))?;
    Ok(file)
}
