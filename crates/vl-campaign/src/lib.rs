//! Campaigns: the lab's experiments run headless and measured, many runs
//! at a time (thesis ch. 7; `vl experiment run` and `matrix`). Each run
//! is a simulated Host on loopback, optionally behind the Media (a relay
//! with a modelled Internet link), and the scripted Guest against it over
//! real sockets: mount, map from the camera, plan, define, then the Host
//! follows the path (navigation) or a scripted operator steers along it
//! from the delayed feedback (teleoperation). The matrix (`matrix`) runs
//! every link profile × pacing × seeds and writes the report (`markdown`,
//! drawn by `vl_client::plots`). It needs both ends of the lab, so it is a
//! crate above the client and the Host, which know nothing of each other.

mod markdown;
mod matrix;
mod runs;
mod stats;

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Serialize;
use vl_core::{
    ARENA_CELL_MM, Arena, ErrorMm, ExperimentId, Experiments, PoseSource, RunComponent, run_svg,
};
use vl_host::{Delays, FramePolicy, Host, HostConfig, Media, MediaConfig, SimCamera, SimLab};
use vl_report::table::count;
use vl_sim::{LinkModel, Optics, Scheduled};

pub use markdown::{headline, write_report};
pub use matrix::{Matrix, MatrixCell, Timing, cells_of, run_all};
pub use runs::RunSeries;
pub use stats::Interval;
use vl_client::plots;
use vl_client::{MeanMax, Pacing, RoundTripMs, Script, ScriptError, ScriptReport, run_script};

/// Why an experiment could not be run or reported.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    #[error("cannot start the simulated Host")]
    Host(#[source] vl_host::HostError),
    #[error("cannot start the Media")]
    Media(#[source] vl_host::MediaError),
    #[error("the run on {arena} with seed {seed}")]
    Run {
        arena: String,
        seed: u64,
        #[source]
        source: ScriptError,
    },
    #[error("a run panicked")]
    Panicked(#[source] tokio::task::JoinError),
    #[error("cannot write {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Draw(#[from] vl_client::plots::PlotError),
}

/// Writes `contents` to `path`, saying which file could not be written.
fn write(path: &Path, contents: impl AsRef<[u8]>) -> Result<(), CampaignError> {
    std::fs::write(path, contents).map_err(|source| CampaignError::Write {
        path: path.to_owned(),
        source,
    })
}

/// Percentiles of one leg's one-way delay, ms.
#[derive(Serialize, Clone, Copy, Debug)]
pub struct Leg {
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
pub struct Legs {
    pub guest_to_host: Option<Leg>,
    pub host_to_guest: Option<Leg>,
    /// Camera frames: from leaving the Host to reaching the Guest.
    pub frames_to_guest: Option<Leg>,
    /// Every delay, for the report's histograms (not in --json).
    #[serde(skip)]
    pub samples: Delays,
}

/// One run, as `--json` gives it.
#[derive(Serialize, Clone, Debug)]
pub struct MeasuredRun {
    pub experiment: ExperimentId,
    /// Whether its experiment is driven by stick: its runs are paced by
    /// the operator's events or by time, where the others' are the Host's.
    #[serde(skip)]
    pub by_stick: bool,
    pub arena: String,
    pub seed: u64,
    /// The link between Guest and Host; none for straight loopback.
    pub profile: Option<String>,
    pub pacing: Pacing,
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
    /// The run against the forecast of its definition (navigation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forecast: Option<vl_core::Gap>,
    /// The predicted pose against the feedback that later arrived, and the
    /// last reported pose against it.
    pub prediction_error_mm: MeanMax,
    pub stale_error_mm: MeanMax,
    pub round_trip_ms: RoundTripMs,
    pub delays: Option<Legs>,
    pub video_bytes: u64,
    pub frames_sent: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub svg: Option<PathBuf>,
    /// The planned and the true path, for the report's pictures.
    #[serde(skip)]
    pub report: Option<ScriptReport>,
}

impl MeasuredRun {
    pub fn succeeded(&self) -> bool {
        self.reached_goal && self.collisions == 0
    }
}

pub fn spread(s: MeanMax) -> String {
    if s.count == 0 {
        "–".into()
    } else {
        format!("{:.1}", s.mean)
    }
}

/// What one run is: everything `run_one` needs.
#[derive(Clone)]
pub struct RunSpec {
    pub experiment: ExperimentId,
    /// What the simulated Host offers, `experiment` among them.
    pub lab: Experiments,
    pub arena: Arena,
    pub seed: u64,
    pub optics: Optics,
    pub compensate_latency: bool,
    pub frames: FramePolicy,
    pub scene: Vec<Scheduled>,
    /// The link's name (as given) and model; none for straight loopback.
    pub link: Option<(String, LinkModel)>,
    pub pacing: Pacing,
    pub timeout: Duration,
    pub progress: bool,
}

/// Runs one experiment: a simulated Host, the Media in front of it when a
/// link is given, and the scripted Guest through it.
pub async fn run_one(spec: &RunSpec) -> Result<MeasuredRun, CampaignError> {
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
        experiments: spec.lab.clone(),
        frames: spec.frames,
        compensate_latency: spec.compensate_latency,
        ..HostConfig::default()
    };
    let host = Host::start_sim(([127, 0, 0, 1], 0).into(), lab, config)
        .await
        .map_err(CampaignError::Host)?;
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
            .map_err(CampaignError::Media)?,
        ),
        None => None,
    };
    let url = media.as_ref().map_or_else(|| host.url(), Media::url);
    let script = Script {
        experiment: Some(spec.experiment.clone()),
        timeout: spec.timeout,
        progress: spec.progress,
        pacing: spec.pacing,
        ..Script::default()
    };
    let report = run_script(&url, &script)
        .await
        .map_err(|source| CampaignError::Run {
            arena: spec.arena.name.clone(),
            seed: spec.seed,
            source,
        })?;
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
    let by_stick = (spec.lab.get(spec.experiment.as_str()))
        .is_ok_and(|o| o.experiment().run.has(RunComponent::Teleoperate));
    Ok(MeasuredRun {
        experiment: spec.experiment.clone(),
        by_stick,
        arena: spec.arena.name.clone(),
        seed: spec.seed,
        profile: spec.link.as_ref().map(|(name, _)| name.clone()),
        pacing: spec.pacing,
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
        forecast: report.forecast,
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

/// A run's outcome in a line of progress.
pub fn progress_line(run: &MeasuredRun) -> String {
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
        "{} on {}, seed {}: {outcome} in {:.1} s, {}{strayed}",
        run.experiment,
        run.arena,
        run.seed,
        run.completion_s,
        count(run.collisions, "collision", "collisions"),
    )
}

/// Over `runs`: the mean of their means, the largest max, the rms of rms.
pub fn overall(runs: &[MeasuredRun], pick: fn(&MeasuredRun) -> Option<ErrorMm>) -> Option<ErrorMm> {
    let all: Vec<ErrorMm> = runs.iter().filter_map(pick).collect();
    (!all.is_empty()).then(|| ErrorMm {
        mean: all.iter().map(|e| e.mean).sum::<f64>() / all.len() as f64,
        max: all.iter().map(|e| e.max).fold(0.0, f64::max),
        rms: (all.iter().map(|e| e.rms * e.rms).sum::<f64>() / all.len() as f64).sqrt(),
    })
}

/// Writes the run's picture (planned, estimated and true paths) into
/// `dir`, named by arena and seed.
pub fn picture(
    dir: &Path,
    arena: &Arena,
    seed: u64,
    report: Option<&ScriptReport>,
) -> Result<PathBuf, CampaignError> {
    let file = dir.join(format!("{}-seed{seed}.svg", arena.name));
    let Some((report, path)) = report.and_then(|r| r.path.as_ref().map(|p| (r, p))) else {
        return Ok(file);
    };
    let svg = run_svg(arena, ARENA_CELL_MM, &report.planned, path).map_err(|e| {
        CampaignError::Draw(plots::PlotError {
            what: format!("arena {}", arena.name),
            why: e.to_string(),
        })
    })?;
    write(&file, svg)?;
    Ok(file)
}
