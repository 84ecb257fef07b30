//! `vl experiment report`: the thesis's chapter 7 as one command. Every link
//! profile × {navigation; teleoperation paced by event; by time} × seeds,
//! run a few at a time, then `report.md` (tables and plots), `report.json`
//! and the plots as SVG and PNG.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use vl_core::{Arena, ExperimentId, Experiments, RunComponent};
use vl_host::{Delays, FramePolicy};
use vl_sim::{LinkModel, Optics};

use super::{CampaignError, Interval, Leg, MeasuredRun, Pacing, RunSpec, overall, run_one};
use vl_client::MeanMax;
use vl_client::plots::{self, EVENT, Marks, TIME};

/// One cell of the matrix, over its seeds.
#[derive(Serialize, Clone)]
pub struct MatrixCell {
    pub experiment: ExperimentId,
    /// Whether its experiment is driven by stick.
    #[serde(skip)]
    pub by_stick: bool,
    pub profile: String,
    pub pacing: Pacing,
    pub runs: usize,
    pub reached_goal: usize,
    pub collisions: u64,
    /// The largest gap in any run, and the violations summed over runs.
    pub max_event_gap: u64,
    pub sync_violations: u64,
    /// Pooled over the runs that succeeded (its max is the largest).
    pub tracking_error_mm: Option<vl_core::ErrorMm>,
    /// Over the seeds that succeeded, each run's figure once: the mean
    /// tracking error, the run's length, and the predictive display's and
    /// the last feedback's mean error. None when none did.
    pub tracking_mm: Option<Interval>,
    pub completion_s: Option<Interval>,
    pub prediction_mm: Option<Interval>,
    pub stale_mm: Option<Interval>,
    /// The Guest's ping round trip, median over runs, ms.
    pub round_trip_p50_ms: f64,
    /// The runs against their forecasts: the mean share their time was
    /// off by, and the mean distance between the paths, mm.
    pub forecast_time_off: Option<f64>,
    pub forecast_path_mm: Option<f64>,
}

/// One profile's legs, pooled over its runs.
#[derive(Serialize)]
pub struct Timing {
    pub profile: String,
    pub guest_to_host: Option<Leg>,
    pub host_to_guest: Option<Leg>,
    pub frames_to_guest: Option<Leg>,
    pub round_trip_p50_ms: f64,
    /// The largest of the runs' p99 round trips.
    pub round_trip_p99_ms: f64,
}

#[derive(Serialize)]
pub struct Matrix {
    pub profiles: Vec<String>,
    pub seeds: u64,
    pub arena: String,
    pub wall_s: f64,
    pub cells: Vec<MatrixCell>,
    pub timing: Vec<Timing>,
    pub runs: Vec<MeasuredRun>,
    /// Event-based runs: every one within one event, none touching anything.
    pub event_based_synchronised: bool,
    pub collisions: u64,
}

impl Matrix {
    /// The matrix of `runs` over the `links` (profile names) they were run
    /// on, `seeds` per cell on `arena`, which took `wall_s`.
    pub fn of(
        links: &[String],
        seeds: u64,
        arena: &str,
        wall_s: f64,
        runs: Vec<MeasuredRun>,
    ) -> Matrix {
        let mut summary = Vec::new();
        let mut timing = Vec::new();
        // The cells in the order their runs were made.
        let mut cells: Vec<(ExperimentId, Pacing)> = Vec::new();
        for r in &runs {
            if !cells
                .iter()
                .any(|(e, p)| *e == r.experiment && *p == r.pacing)
            {
                cells.push((r.experiment.clone(), r.pacing));
            }
        }
        for name in links {
            for (experiment, pacing) in cells.iter().cloned() {
                let these: Vec<&MeasuredRun> = runs
                    .iter()
                    .filter(|r| {
                        r.profile.as_deref() == Some(name)
                            && r.experiment == experiment
                            && r.pacing == pacing
                    })
                    .collect();
                if !these.is_empty() {
                    summary.push(cell(&these));
                }
            }
            let of = |r: &&MeasuredRun| r.profile.as_deref() == Some(name.as_str());
            let pooled = |pick: fn(&Delays) -> &Vec<f64>| -> Vec<f64> {
                runs.iter()
                    .filter(of)
                    .filter_map(|r| r.delays.as_ref())
                    .flat_map(|d| pick(&d.samples).iter().copied())
                    .collect()
            };
            let mut rtt: Vec<f64> = runs
                .iter()
                .filter(of)
                .map(|r| r.round_trip_ms.p50)
                .collect();
            rtt.sort_by(f64::total_cmp);
            let mut rtt99: Vec<f64> = runs
                .iter()
                .filter(of)
                .map(|r| r.round_trip_ms.p99)
                .collect();
            rtt99.sort_by(f64::total_cmp);
            timing.push(Timing {
                profile: name.clone(),
                guest_to_host: Leg::of(&pooled(|d| &d.to_host)),
                host_to_guest: Leg::of(&pooled(|d| &d.to_guest)),
                frames_to_guest: Leg::of(&pooled(|d| &d.frames_to_guest)),
                round_trip_p50_ms: rtt.get(rtt.len() / 2).copied().unwrap_or(f64::NAN),
                round_trip_p99_ms: rtt99.last().copied().unwrap_or(f64::NAN),
            });
        }
        Matrix {
            profiles: links.to_vec(),
            seeds,
            arena: arena.to_owned(),
            wall_s,
            event_based_synchronised: runs
                .iter()
                .filter(|r| r.pacing == Pacing::Event)
                .all(|r| r.max_event_gap <= 1 && r.sync_violations == 0),
            collisions: runs.iter().map(|r| r.collisions).sum(),
            cells: summary,
            timing,
            runs,
        }
    }

    /// The first teleoperation run on `profile` paced so that succeeded.
    fn teleop(&self, profile: &str, pacing: Pacing) -> Option<&MeasuredRun> {
        self.runs.iter().find(|r| {
            r.by_stick
                && r.profile.as_deref() == Some(profile)
                && r.pacing == pacing
                && r.succeeded()
        })
    }
}

/// A cell of the matrix: how many of its runs reached the goal, and the
/// figures of those that succeeded (a failed run's would mislead; the
/// report lists it with why it ended).
fn cell(all: &[&MeasuredRun]) -> MatrixCell {
    let first = all[0];
    let runs: Vec<&MeasuredRun> = all.iter().copied().filter(|r| r.succeeded()).collect();
    let owned: Vec<MeasuredRun> = runs.iter().map(|r| (*r).clone()).collect();
    let means = |pick: fn(&MeasuredRun) -> MeanMax| {
        Interval::of(
            runs.iter()
                .map(|r| pick(r))
                .filter(|s| s.count > 0)
                .map(|s| s.mean),
        )
    };
    // The link's round trip is the link's, whatever became of the run.
    let mut rtts: Vec<f64> = all.iter().map(|r| r.round_trip_ms.p50).collect();
    rtts.sort_by(f64::total_cmp);
    MatrixCell {
        experiment: first.experiment.clone(),
        by_stick: first.by_stick,
        profile: first.profile.clone().unwrap_or_default(),
        pacing: first.pacing,
        runs: all.len(),
        reached_goal: all.iter().filter(|r| r.reached_goal).count(),
        collisions: all.iter().map(|r| r.collisions).sum(),
        max_event_gap: all.iter().map(|r| r.max_event_gap).max().unwrap_or(0),
        sync_violations: all.iter().map(|r| r.sync_violations).sum(),
        tracking_error_mm: overall(&owned, |r| r.tracking_error_mm),
        tracking_mm: Interval::of(
            runs.iter()
                .filter_map(|r| r.tracking_error_mm)
                .map(|e| e.mean),
        ),
        completion_s: Interval::of(runs.iter().map(|r| r.completion_s)),
        prediction_mm: means(|r| r.prediction_error_mm),
        stale_mm: means(|r| r.stale_error_mm),
        round_trip_p50_ms: rtts[rtts.len() / 2],
        forecast_time_off: mean(
            all.iter()
                .filter_map(|r| r.forecast?.time_off())
                .map(f64::abs),
        ),
        forecast_path_mm: mean(
            all.iter()
                .filter_map(|r| r.forecast)
                .map(|g| g.path_mean_mm),
        ),
    }
}

/// The mean of `values`; none of none.
fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0u32), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / f64::from(n))
}

/// The cells of the matrix: each experiment `lab` offers, those driven by
/// stick paced by event and by time.
fn cells(lab: &Experiments) -> Vec<(ExperimentId, Pacing)> {
    let mut cells = Vec::new();
    for experiment in lab.experiments() {
        cells.push((experiment.id.clone(), Pacing::Event));
        if experiment.run.has(RunComponent::Teleoperate) {
            cells.push((experiment.id.clone(), Pacing::Time));
        }
    }
    cells
}

/// The runs of every cell of the experiments `lab` offers on every link,
/// `seeds` seeds from `seed` each.
pub fn cells_of(
    lab: &Experiments,
    links: &[(String, LinkModel)],
    arena: &Arena,
    seeds: std::ops::Range<u64>,
    timeout: Duration,
) -> Vec<RunSpec> {
    let mut specs = Vec::new();
    for link in links {
        for (experiment, pacing) in cells(lab) {
            for seed in seeds.clone() {
                specs.push(RunSpec {
                    experiment: experiment.clone(),
                    lab: lab.clone(),
                    arena: arena.clone(),
                    seed,
                    optics: Optics {
                        seed,
                        ..Optics::default()
                    },
                    compensate_latency: true,
                    frames: FramePolicy::EveryFrame,
                    scene: Vec::new(),
                    link: Some(link.clone()),
                    pacing,
                    timeout,
                    progress: false,
                });
            }
        }
    }
    specs
}

/// Runs `specs`, `jobs` at a time, telling `finished` of each as it ends
/// (how many have, and the run); the runs come back in the order of `specs`.
pub async fn run_all(
    specs: Vec<RunSpec>,
    jobs: usize,
    mut finished: impl FnMut(usize, &MeasuredRun),
) -> Result<Vec<MeasuredRun>, CampaignError> {
    let total = specs.len();
    let slots = Arc::new(tokio::sync::Semaphore::new(jobs.max(1)));
    let mut tasks = tokio::task::JoinSet::new();
    for (i, spec) in specs.into_iter().enumerate() {
        let slots = slots.clone();
        tasks.spawn(async move {
            let _slot = slots.acquire_owned().await;
            (i, run_one(&spec).await)
        });
    }
    let mut runs: Vec<Option<MeasuredRun>> = vec![None; total];
    let mut done = 0;
    while let Some(joined) = tasks.join_next().await {
        let (i, run) = joined.map_err(CampaignError::Panicked)?;
        let run = run?;
        done += 1;
        finished(done, &run);
        runs[i] = Some(run);
    }
    Ok(runs.into_iter().flatten().collect())
}

/// The pictures, by what they show: (caption, PNG file name).
pub(super) fn draw(
    dir: &Path,
    m: &Matrix,
    arena: &Arena,
) -> Result<Vec<(String, PathBuf)>, CampaignError> {
    let mut out = Vec::new();
    // Link profiles are categories (ordered by their round trip), not a
    // continuous axis: each cell a mean with its 95 % interval, unjoined.
    let mut by_rtt: Vec<&Timing> = m.timing.iter().collect();
    by_rtt.sort_by(|a, b| a.round_trip_p50_ms.total_cmp(&b.round_trip_p50_ms));
    let profiles: Vec<String> = by_rtt.iter().map(|t| t.profile.clone()).collect();
    let by_profile = |pacing: Pacing, pick: fn(&MatrixCell) -> Option<Interval>| {
        profiles
            .iter()
            .map(|p| {
                m.cells
                    .iter()
                    .find(|c| c.by_stick && c.pacing == pacing && &c.profile == p)
                    .and_then(pick)
                    .map(|i| (i.mean, i.low(), i.high()))
            })
            .collect::<Vec<_>>()
    };
    out.push((
        "Tracking error by link profile: teleoperation, event-based against time-based (mean over seeds, 95 % interval)"
            .to_owned(),
        plots::intervals(
            dir,
            "tracking-by-profile",
            "Teleoperation: tracking error by link",
            ("link profile (by round trip)", "mean distance of the true path to the planned, mm"),
            &profiles,
            &[
                ("event-based".into(), EVENT, by_profile(Pacing::Event, |c| c.tracking_mm)),
                ("time-based".into(), TIME, by_profile(Pacing::Time, |c| c.tracking_mm)),
            ],
        )?,
    ));
    out.push((
        "The predictive display's error by link profile, beside showing the last feedback alone (event-based; mean over seeds, 95 % interval)".to_owned(),
        plots::intervals(
            dir,
            "prediction-by-profile",
            "Predicted pose against the last reported pose (event-based)",
            ("link profile (by round trip)", "mean error against the next feedback, mm"),
            &profiles,
            &[
                ("predicted (ghost)".into(), EVENT, by_profile(Pacing::Event, |c| c.prediction_mm)),
                ("last reported".into(), TIME, by_profile(Pacing::Event, |c| c.stale_mm)),
            ],
        )?,
    ));
    for t in &m.timing {
        out.extend(profile_pictures(dir, m, t, arena)?);
    }
    Ok(out)
}

/// The pictures of one profile's runs: the legs' delays, the
/// synchronisation over time, and the paths driven.
fn profile_pictures(
    dir: &Path,
    m: &Matrix,
    t: &Timing,
    arena: &Arena,
) -> Result<Vec<(String, PathBuf)>, CampaignError> {
    let mut out = Vec::new();
    let teleop = |pacing: Pacing| m.teleop(&t.profile, pacing);
    let runs: Vec<&MeasuredRun> = m
        .runs
        .iter()
        .filter(|r| r.profile.as_deref() == Some(t.profile.as_str()))
        .collect();
    let up: Vec<f64> = runs
        .iter()
        .filter_map(|r| r.delays.as_ref())
        .flat_map(|d| d.samples.to_host.iter().copied())
        .collect();
    let down: Vec<f64> = runs
        .iter()
        .filter_map(|r| r.delays.as_ref())
        .flat_map(|d| d.samples.to_guest.iter().copied())
        .collect();
    let frames: Vec<f64> = runs
        .iter()
        .filter_map(|r| r.delays.as_ref())
        .flat_map(|d| d.samples.frames_to_guest.iter().copied())
        .collect();
    out.push((
        format!("One-way delays on {}", t.profile),
        plots::delays(
            dir,
            &format!("delays-{}", t.profile),
            &format!("One-way delays: {}", t.profile),
            &[
                ("Guest to Host", &up),
                ("Host to Guest", &down),
                ("frames to Guest", &frames),
            ],
        )?,
    ));
    let trace = |pacing: Pacing| -> Vec<(f64, f64)> {
        teleop(pacing)
            .and_then(|r| r.report.as_ref())
            .map(|r| r.gaps.iter().map(|&(s, g)| (s, g as f64)).collect())
            .unwrap_or_default()
    };
    out.push((
        format!("Synchronisation over time on {}: each command's event ahead of the feedback it was sent on", t.profile),
        plots::lines(
            dir,
            &format!("sync-{}", t.profile),
            &format!("Synchronisation: {}", t.profile),
            ("seconds into the run", "command event − feedback event seen"),
            &[
                ("event-based".into(), EVENT, trace(Pacing::Event)),
                ("time-based".into(), TIME, trace(Pacing::Time)),
            ],
            Marks::Lines,
        )?,
    ));
    let taken = |pacing: Pacing, label: &str, colour| {
        teleop(pacing)
            .and_then(|r| r.report.as_ref())
            .and_then(|r| r.path.as_ref())
            .map(|p| (label.to_owned(), colour, p.truth.clone()))
    };
    let planned = teleop(Pacing::Event)
        .and_then(|r| r.report.as_ref())
        .map(|r| r.planned.clone())
        .unwrap_or_default();
    let paths: Vec<_> = [
        taken(Pacing::Event, "event-based", EVENT),
        taken(Pacing::Time, "time-based", TIME),
    ]
    .into_iter()
    .flatten()
    .collect();
    out.push((
        format!(
            "Paths driven by the scripted operator on {} (first seed)",
            t.profile
        ),
        plots::paths(
            dir,
            &format!("paths-{}", t.profile),
            &format!("Teleoperation paths: {}", t.profile),
            arena,
            &planned,
            &paths,
        )?,
    ));
    Ok(out)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use vl_client::RoundTripMs;
    use vl_core::{ErrorMm, PoseSource};

    /// A run on `profile` that reached its goal or not, with a tracking
    /// error of mean `track` (max twice that) and a round trip of `rtt` ms.
    pub(crate) fn run(
        experiment: &str,
        pacing: Pacing,
        profile: &str,
        reached: bool,
        track: f64,
        rtt: f64,
    ) -> MeasuredRun {
        MeasuredRun {
            experiment: ExperimentId::new(experiment).unwrap(),
            by_stick: experiment == "teleoperation",
            arena: "open".into(),
            seed: 0,
            profile: Some(profile.into()),
            pacing,
            reached_goal: reached,
            end: if reached {
                "goal reached"
            } else {
                "time limit"
            }
            .into(),
            pose_source: PoseSource::default(),
            collisions: u64::from(!reached),
            commands: 10,
            max_event_gap: if pacing == Pacing::Time { 4 } else { 1 },
            sync_violations: if pacing == Pacing::Time { 3 } else { 0 },
            tracking_error_mm: Some(ErrorMm {
                mean: track,
                max: 2.0 * track,
                rms: track,
            }),
            estimate_error_mm: None,
            completion_s: 10.0,
            forecast: None,
            prediction_error_mm: MeanMax::default(),
            stale_error_mm: MeanMax::default(),
            round_trip_ms: RoundTripMs {
                p50: rtt,
                p99: 2.0 * rtt,
            },
            delays: None,
            video_bytes: 0,
            frames_sent: 0,
            svg: None,
            report: None,
        }
    }

    #[test]
    fn a_leg_s_percentiles_are_nearest_ranks() {
        let ms: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let leg = Leg::of(&ms).expect("a leg");
        assert_eq!(
            (leg.messages, leg.p50, leg.p90, leg.p99, leg.max),
            (100, 50.0, 90.0, 99.0, 100.0)
        );
        assert!(Leg::of(&[]).is_none());
    }

    #[test]
    fn over_all_runs_means_are_averaged_and_maxima_kept() {
        let runs = [
            run("navigation", Pacing::Event, "lan", true, 2.0, 1.0),
            run("navigation", Pacing::Event, "lan", true, 4.0, 1.0),
        ];
        let e = overall(&runs, |r| r.tracking_error_mm).expect("errors");
        assert_eq!((e.mean, e.max), (3.0, 8.0));
        assert!((e.rms - 10f64.sqrt()).abs() < 1e-12);
        assert!(overall(&runs, |r| r.estimate_error_mm).is_none());
    }

    #[test]
    fn a_cell_counts_every_run_and_measures_only_those_that_succeeded() {
        let runs = [
            run("teleoperation", Pacing::Event, "lan", true, 2.0, 3.0),
            run("teleoperation", Pacing::Event, "lan", false, 50.0, 5.0),
            run("teleoperation", Pacing::Event, "lan", true, 4.0, 4.0),
        ];
        let c = cell(&runs.iter().collect::<Vec<_>>());
        assert_eq!((c.runs, c.reached_goal, c.collisions), (3, 2, 1));
        assert_eq!(
            c.tracking_error_mm.map(|e| e.mean),
            Some(3.0),
            "the failed run left out"
        );
        // The link's round trip is the median over every run, failed or not.
        assert_eq!(c.round_trip_p50_ms, 4.0);
    }

    #[test]
    fn the_matrix_has_a_cell_per_profile_and_pacing_and_judges_event_pacing() {
        let runs = vec![
            run("navigation", Pacing::Event, "lan", true, 1.0, 1.0),
            run("teleoperation", Pacing::Event, "lan", true, 2.0, 1.0),
            run("teleoperation", Pacing::Time, "lan", true, 3.0, 1.0),
            run("teleoperation", Pacing::Event, "far", true, 5.0, 300.0),
        ];
        let links = ["lan".to_owned(), "far".to_owned()];
        let m = Matrix::of(&links, 1, "open", 1.0, runs.clone());
        assert_eq!(m.cells.len(), 4);
        assert_eq!(m.timing.len(), 2);
        assert_eq!(m.timing[1].round_trip_p50_ms, 300.0);
        assert!(
            m.event_based_synchronised,
            "time pacing's gaps do not count"
        );
        let mut late = runs;
        late[1].max_event_gap = 2;
        assert!(!Matrix::of(&links, 1, "open", 1.0, late).event_based_synchronised);
    }
}
