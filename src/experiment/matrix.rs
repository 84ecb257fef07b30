//! `vl experiment report`: the thesis's chapter 7 as one command. Every link
//! profile × {navigation; teleoperation event-based; teleoperation time-based} × seeds, run
//! a few at a time, then `report.md` (tables and plots), `report.json` and
//! the plots as SVG and PNG.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;
use vl_core::{Experiment, Named};
use vl_host::FramePolicy;
use vl_sim::{LinkModel, Optics, Profile};

use super::plots::{self, EVENT, TIME};
use super::{Control, Leg, Run, RunSpec, line, run_one};
use crate::input::{load_arena, seconds};
use crate::report::{Report, Table, emit, yes};

#[derive(Args)]
pub(crate) struct ReportArgs {
    /// Where to write report.md, report.json and the plots.
    #[arg(long)]
    out: PathBuf,
    /// Seeds per cell (profile × experiment × control).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=100))]
    seeds: u64,
    /// The first seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Link profiles, comma-separated (default: every shipped one).
    #[arg(long, value_delimiter = ',')]
    profiles: Vec<String>,
    /// The arena every run drives in.
    #[arg(long, default_value = "navigation")]
    arena: String,
    /// Runs at once (each is a lab, a relay and a Guest).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=16))]
    jobs: u64,
    /// Give up on a run after this many seconds.
    #[arg(long, default_value_t = 120.0)]
    timeout: f64,
    /// Print the summary as JSON (report.json is written either way).
    #[arg(long)]
    json: bool,
}

/// One cell of the matrix, over its seeds.
#[derive(Serialize, Clone)]
struct Cell {
    experiment: Experiment,
    profile: String,
    control: Control,
    runs: usize,
    reached_goal: usize,
    collisions: u64,
    /// The largest gap in any run, and the violations summed over runs.
    max_event_gap: u64,
    sync_violations: u64,
    tracking_error_mm: Option<vl_core::ErrorMm>,
    /// Of the runs that succeeded: none when none did.
    completion_s: Option<f64>,
    prediction_error_mm: Option<[f64; 2]>,
    stale_error_mm: Option<[f64; 2]>,
    /// The Guest's ping round trip, median over runs, ms.
    round_trip_p50_ms: f64,
}

/// One profile's legs, pooled over its runs.
#[derive(Serialize)]
struct Timing {
    profile: String,
    guest_to_host: Option<Leg>,
    host_to_guest: Option<Leg>,
    frames_to_guest: Option<Leg>,
    round_trip_p50_ms: f64,
    /// The largest of the runs' p99 round trips.
    round_trip_p99_ms: f64,
}

#[derive(Serialize)]
struct Matrix {
    profiles: Vec<String>,
    seeds: u64,
    arena: String,
    wall_s: f64,
    cells: Vec<Cell>,
    timing: Vec<Timing>,
    runs: Vec<Run>,
    /// Event-based runs: every one within one event, none touching anything.
    event_based_synchronised: bool,
    collisions: u64,
}

impl Report for Matrix {
    fn table(&self) -> Table {
        let mut table = headline(&self.cells);
        for r in self.runs.iter().filter(|r| !r.succeeded()) {
            table = table.note(format!(
                "failed: {} on {}, {} control, seed {}: {} ({} collisions); left out of the figures",
                r.experiment,
                r.profile.as_deref().unwrap_or("loopback"),
                format!("{:?}", r.control).to_lowercase(),
                r.seed,
                r.end,
                r.collisions
            ));
        }
        table
            .title(format!(
                "{} runs on {} in {:.0} s",
                self.runs.len(),
                self.arena,
                self.wall_s
            ))
            .note(format!(
                "event-based runs synchronised (gap ≤ 1 at every command): {}; collisions: {}",
                yes(self.event_based_synchronised),
                self.collisions
            ))
    }
}

fn headline(cells: &[Cell]) -> Table {
    let mut table = Table::columns(&[
        "experiment",
        "profile",
        "control",
        "goal",
        "collisions",
        "max gap",
        "sync lost",
        "track mean",
        "track max",
        "seconds",
        "predict mean",
        "predict max",
        "stale mean",
        "rtt p50",
    ]);
    let pair = |v: Option<[f64; 2]>, k: usize| v.map_or("–".into(), |v| format!("{:.1}", v[k]));
    for c in cells {
        table.row(vec![
            c.experiment.to_string(),
            c.profile.clone(),
            match (c.experiment, c.control) {
                (Experiment::Navigation, _) => "host".into(),
                (_, Control::Event) => "event".into(),
                (_, Control::Time) => "time".into(),
            },
            format!("{}/{}", c.reached_goal, c.runs),
            c.collisions.to_string(),
            c.max_event_gap.to_string(),
            c.sync_violations.to_string(),
            c.tracking_error_mm
                .map_or("–".into(), |e| format!("{:.1}", e.mean)),
            c.tracking_error_mm
                .map_or("–".into(), |e| format!("{:.1}", e.max)),
            c.completion_s.map_or("–".into(), |s| format!("{s:.1}")),
            pair(c.prediction_error_mm, 0),
            pair(c.prediction_error_mm, 1),
            pair(c.stale_error_mm, 0),
            format!("{:.0}", c.round_trip_p50_ms),
        ]);
    }
    table
}

/// A cell of the matrix: how many of its runs reached the goal, and the
/// figures of those that succeeded (a failed run's would mislead; the
/// report lists it with why it ended).
fn cell(all: &[&Run]) -> Cell {
    let first = all[0];
    let runs: Vec<&Run> = all.iter().copied().filter(|r| r.succeeded()).collect();
    let owned: Vec<Run> = runs.iter().map(|r| (*r).clone()).collect();
    let spreads = |pick: fn(&Run) -> vl_guest::Spread| {
        let s: Vec<vl_guest::Spread> = runs
            .iter()
            .map(|r| pick(r))
            .filter(|s| s.count > 0)
            .collect();
        (!s.is_empty()).then(|| {
            [
                s.iter().map(|s| s.mean).sum::<f64>() / s.len() as f64,
                s.iter().map(|s| s.max).fold(0.0, f64::max),
            ]
        })
    };
    // The link's round trip is the link's, whatever became of the run.
    let mut rtts: Vec<f64> = all.iter().map(|r| r.round_trip_ms.p50).collect();
    rtts.sort_by(f64::total_cmp);
    Cell {
        experiment: first.experiment,
        profile: first.profile.clone().unwrap_or_default(),
        control: first.control,
        runs: all.len(),
        reached_goal: all.iter().filter(|r| r.reached_goal).count(),
        collisions: all.iter().map(|r| r.collisions).sum(),
        max_event_gap: all.iter().map(|r| r.max_event_gap).max().unwrap_or(0),
        sync_violations: all.iter().map(|r| r.sync_violations).sum(),
        tracking_error_mm: super::overall(&owned, |r| r.tracking_error_mm),
        completion_s: (!runs.is_empty())
            .then(|| runs.iter().map(|r| r.completion_s).sum::<f64>() / runs.len() as f64),
        prediction_error_mm: spreads(|r| r.prediction_error_mm),
        stale_error_mm: spreads(|r| r.stale_error_mm),
        round_trip_p50_ms: rtts[rtts.len() / 2],
    }
}

pub(crate) fn report(runtime: &tokio::runtime::Runtime, args: ReportArgs) -> Result<ExitCode> {
    let timeout = seconds("--timeout", args.timeout)?;
    let names: Vec<String> = if args.profiles.is_empty() {
        Profile::ALL.iter().map(|p| p.id().to_owned()).collect()
    } else {
        args.profiles.clone()
    };
    let links: Vec<(String, LinkModel)> = names
        .iter()
        .map(|n| Ok((n.clone(), crate::media::load(n)?)))
        .collect::<Result<_>>()?;
    let arena = load_arena(&args.arena)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let cells = [
        (Experiment::Navigation, Control::Event),
        (Experiment::Teleoperation, Control::Event),
        (Experiment::Teleoperation, Control::Time),
    ];
    let mut specs = Vec::new();
    for link in &links {
        for &(experiment, control) in &cells {
            for k in 0..args.seeds {
                let seed = args.seed + k;
                specs.push(RunSpec {
                    experiment,
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
                    control,
                    timeout,
                    progress: false,
                });
            }
        }
    }
    let total = specs.len();
    let started = Instant::now();
    eprintln!(
        "vl experiment report: {total} runs ({} profiles × navigation, teleoperation event, teleoperation time × {} seeds), {} at a time",
        links.len(),
        args.seeds,
        args.jobs
    );
    let runs = runtime.block_on(async {
        let slots = Arc::new(tokio::sync::Semaphore::new(args.jobs as usize));
        let mut tasks = tokio::task::JoinSet::new();
        for (i, spec) in specs.into_iter().enumerate() {
            let slots = slots.clone();
            tasks.spawn(async move {
                let _slot = slots.acquire_owned().await;
                (i, run_one(&spec).await)
            });
        }
        let mut runs: Vec<Option<Run>> = vec![None; total];
        let mut finished = 0;
        while let Some(joined) = tasks.join_next().await {
            let (i, run) = joined.context("a run panicked")?;
            let run = run?;
            finished += 1;
            eprintln!(
                "[{finished}/{total}] {:.0} s  {} {} {}: {}",
                started.elapsed().as_secs_f64(),
                run.experiment,
                run.profile.as_deref().unwrap_or("loopback"),
                format!("{:?}", run.control).to_lowercase(),
                line(&run)
            );
            runs[i] = Some(run);
        }
        anyhow::Ok(runs.into_iter().flatten().collect::<Vec<Run>>())
    })?;

    let mut summary = Vec::new();
    let mut timing = Vec::new();
    for (name, _) in &links {
        for &(experiment, control) in &cells {
            let these: Vec<&Run> = runs
                .iter()
                .filter(|r| {
                    r.profile.as_deref() == Some(name)
                        && r.experiment == experiment
                        && r.control == control
                })
                .collect();
            if !these.is_empty() {
                summary.push(cell(&these));
            }
        }
        let of = |r: &&Run| r.profile.as_deref() == Some(name.as_str());
        let pooled = |pick: fn(&vl_host::Delays) -> &Vec<f64>| -> Vec<f64> {
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
    let matrix = Matrix {
        profiles: names,
        seeds: args.seeds,
        arena: arena.name.clone(),
        wall_s: started.elapsed().as_secs_f64(),
        event_based_synchronised: runs
            .iter()
            .filter(|r| r.control == Control::Event)
            .all(|r| r.max_event_gap <= 1 && r.sync_violations == 0),
        collisions: runs.iter().map(|r| r.collisions).sum(),
        cells: summary,
        timing,
        runs,
    };
    let pictures = draw(&args.out, &matrix, &arena)?;
    write_markdown(&args.out, &matrix, &pictures)?;
    let json = args.out.join("report.json");
    std::fs::write(&json, serde_json::to_string_pretty(&matrix)?)
        .with_context(|| format!("cannot write {}", json.display()))?;
    emit(&matrix, args.json)?;
    if !args.json {
        println!(
            "wrote {} and {}",
            args.out.join("report.md").display(),
            json.display()
        );
    }
    Ok(
        if matrix.event_based_synchronised && matrix.collisions == 0 {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        },
    )
}

/// The pictures, by what they show: (caption, PNG file name).
fn draw(dir: &Path, m: &Matrix, arena: &vl_core::Arena) -> Result<Vec<(String, PathBuf)>> {
    let mut out = Vec::new();
    let teleop = |profile: &str, control: Control| -> Option<&Run> {
        m.runs.iter().find(|r| {
            r.experiment == Experiment::Teleoperation
                && r.profile.as_deref() == Some(profile)
                && r.control == control
                && r.succeeded()
        })
    };
    // Tracking and prediction against the round trip, event against time.
    let by_delay = |control: Control, pick: fn(&Cell) -> Option<f64>| -> Vec<(f64, f64)> {
        let mut v: Vec<(f64, f64)> = m
            .cells
            .iter()
            .filter(|c| c.experiment == Experiment::Teleoperation && c.control == control)
            .filter_map(|c| pick(c).map(|y| (c.round_trip_p50_ms, y)))
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v
    };
    let tracking = |c: &Cell| c.tracking_error_mm.map(|e| e.mean);
    out.push((
        "Tracking error against the round trip: teleoperation, event-based against time-based"
            .to_owned(),
        plots::lines(
            dir,
            "tracking-vs-delay",
            "Teleoperation: tracking error against delay",
            (
                "round trip, ms (median of the Guest's pings)",
                "mean distance of the true path to the planned, mm",
            ),
            &[
                (
                    "event-based".into(),
                    EVENT,
                    by_delay(Control::Event, tracking),
                ),
                ("time-based".into(), TIME, by_delay(Control::Time, tracking)),
            ],
            true,
        )?,
    ));
    let predicted = |c: &Cell| c.prediction_error_mm.map(|e| e[0]);
    let stale = |c: &Cell| c.stale_error_mm.map(|e| e[0]);
    out.push((
        "The predictive display's error against the round trip, beside showing the last feedback alone".to_owned(),
        plots::lines(
            dir,
            "prediction-vs-delay",
            "Predicted pose against the last reported pose (event-based)",
            ("round trip, ms", "mean error against the next feedback, mm"),
            &[
                ("predicted (ghost)".into(), EVENT, by_delay(Control::Event, predicted)),
                ("last reported".into(), TIME, by_delay(Control::Event, stale)),
            ],
            true,
        )?,
    ));
    for t in &m.timing {
        let runs: Vec<&Run> = m
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
        let trace = |control: Control| -> Vec<(f64, f64)> {
            teleop(&t.profile, control)
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
                    ("event-based".into(), EVENT, trace(Control::Event)),
                    ("time-based".into(), TIME, trace(Control::Time)),
                ],
                false,
            )?,
        ));
        let taken = |control: Control, label: &str, colour| {
            teleop(&t.profile, control)
                .and_then(|r| r.report.as_ref())
                .and_then(|r| r.path.as_ref())
                .map(|p| (label.to_owned(), colour, p.truth.clone()))
        };
        let planned = teleop(&t.profile, Control::Event)
            .and_then(|r| r.report.as_ref())
            .map(|r| r.planned.clone())
            .unwrap_or_default();
        let paths: Vec<_> = [
            taken(Control::Event, "event-based", EVENT),
            taken(Control::Time, "time-based", TIME),
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
                (arena.width_mm, arena.height_mm),
                &planned,
                &paths,
            )?,
        ));
    }
    Ok(out)
}

fn ms(v: Option<Leg>) -> [String; 4] {
    match v {
        Some(l) => [l.p50, l.p90, l.p99, l.max].map(|x| format!("{x:.1}")),
        None => ["–".into(), "–".into(), "–".into(), "–".into()],
    }
}

fn write_markdown(dir: &Path, m: &Matrix, pictures: &[(String, PathBuf)]) -> Result<()> {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# The Internet in the loop: event-based against time-based control\n"
    );
    let _ = writeln!(
        md,
        "{} runs on the `{}` arena, {} seed(s) per cell, over the Media (`vl media`) with each link \
         profile; {:.0} s of wall time. Written by `vl experiment report`.\n",
        m.runs.len(),
        m.arena,
        m.seeds,
        m.wall_s
    );
    let _ = writeln!(
        md,
        "*navigation*: the Host follows the planned path from the camera's estimate (the Guest sends no \
         commands, so pacing does not apply). *teleoperation*: a scripted operator steers toward waypoints \
         along the planned path from the feedback it sees, sending commands either after each \
         feedback (*event*) or every 20 ms (*time*). Errors in mm; *max gap*: the largest number \
         of events a command ran ahead of the feedback it was sent on (event-based control keeps \
         it at 1); *sync lost*: commands more than one event ahead; *predict*: the predictive \
         display's pose against the feedback that came next; *stale*: the last reported pose \
         against it.\n"
    );
    let _ = writeln!(md, "## Results\n\n```\n{}```\n", headline(&m.cells));
    let failed: Vec<&Run> = m.runs.iter().filter(|r| !r.succeeded()).collect();
    if !failed.is_empty() {
        let _ = writeln!(
            md,
            "### Runs that failed\n\nCounted in *goal* above, left out of every other figure and \
             picture:\n"
        );
        let mut t = Table::columns(&[
            "experiment",
            "profile",
            "control",
            "seed",
            "ended",
            "collisions",
        ]);
        for r in failed {
            t.row(vec![
                r.experiment.to_string(),
                r.profile.clone().unwrap_or_default(),
                format!("{:?}", r.control).to_lowercase(),
                r.seed.to_string(),
                r.end.clone(),
                r.collisions.to_string(),
            ]);
        }
        let _ = writeln!(md, "```\n{t}```\n");
    }
    let _ = writeln!(
        md,
        "Event-based runs synchronised at every command: **{}**. Collisions over all runs: **{}**.\n",
        yes(m.event_based_synchronised),
        m.collisions
    );
    let _ = writeln!(md, "## Time analysis (thesis §7.4.3)\n");
    let _ = writeln!(
        md,
        "One-way delays each message was held for, in ms, measured at the Media on one clock \
         (frames: from leaving the Host's socket to reaching the Guest's; the Host's capture and \
         encoding time is not in it); round trips measured by the Guest's pings (end to end, \
         through the Host's WebSocket task; the p99 is the largest run's).\n"
    );
    let mut t = Table::columns(&["profile", "leg", "messages", "p50", "p90", "p99", "max"]);
    for timing in &m.timing {
        for (leg, v) in [
            ("Guest → Host", timing.guest_to_host),
            ("Host → Guest", timing.host_to_guest),
            ("frames → Guest", timing.frames_to_guest),
        ] {
            let [a, b, c, d] = ms(v);
            let messages = v.map_or("0".into(), |l| l.messages.to_string());
            t.row(vec![
                timing.profile.clone(),
                leg.into(),
                messages,
                a,
                b,
                c,
                d,
            ]);
        }
        t.row(vec![
            timing.profile.clone(),
            "round trip (pings)".into(),
            String::new(),
            format!("{:.1}", timing.round_trip_p50_ms),
            String::new(),
            format!("{:.1}", timing.round_trip_p99_ms),
            String::new(),
        ]);
    }
    let _ = writeln!(md, "```\n{t}```\n");
    let _ = writeln!(md, "## Pictures\n");
    for (caption, png) in pictures {
        let svg = png.with_extension("svg");
        let _ = writeln!(
            md,
            "### {caption}\n\n![{caption}]({})\n\n([SVG]({}))\n",
            png.display(),
            svg.display()
        );
    }
    let file = dir.join("report.md");
    std::fs::write(&file, md).with_context(|| format!("cannot write {}", file.display()))
}
