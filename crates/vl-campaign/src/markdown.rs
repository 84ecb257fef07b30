//! The matrix's report as Markdown: its figures, the runs that failed, the
//! time analysis and the pictures.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use vl_report::table::{self, Report, Table, yes};

use vl_core::Arena;

use super::Pacing;
use super::matrix::{Matrix, MatrixCell, draw};
use super::{CampaignError, Interval, Leg, MeasuredRun};

fn ms(v: Option<Leg>) -> [String; 4] {
    match v {
        Some(l) => [l.p50, l.p90, l.p99, l.max].map(|x| format!("{x:.1}")),
        None => ["–".into(), "–".into(), "–".into(), "–".into()],
    }
}

/// Writes report.md, report.json and the pictures into `dir`, drawing
/// the paths over `arena`.
pub fn write_report(dir: &Path, m: &Matrix, arena: &Arena) -> Result<(), CampaignError> {
    let pictures = draw(dir, m, arena)?;
    write(dir, m, &pictures)?;
    let json = serde_json::to_string_pretty(m).map_err(|e| {
        CampaignError::Draw(vl_client::plots::PlotError {
            what: "report.json".into(),
            why: e.to_string(),
        })
    })?;
    super::write(&dir.join("report.json"), json)
}

fn pacing_of(c: &MatrixCell) -> &'static str {
    match (c.by_stick, c.pacing) {
        (false, _) => "host",
        (true, Pacing::Event) => "event",
        (true, Pacing::Time) => "time",
    }
}

/// The matrix's outcomes, a row per cell: goals, contacts, synchronisation.
pub(crate) fn outcomes(cells: &[MatrixCell]) -> Table {
    let mut table = Table::columns(&[
        "experiment",
        "profile",
        "pacing",
        "goal",
        "collisions",
        "max gap",
        "sync lost",
        "rtt p50, ms",
    ]);
    for c in cells {
        table.row(vec![
            c.experiment.to_string(),
            c.profile.clone(),
            pacing_of(c).into(),
            format!("{}/{}", c.reached_goal, c.runs),
            c.collisions.to_string(),
            c.max_event_gap.to_string(),
            c.sync_violations.to_string(),
            format!("{:.0}", c.round_trip_p50_ms),
        ]);
    }
    table
}

/// The matrix's figures, a row per cell: each a mean over the seeds that
/// succeeded with its 95 % interval.
pub fn headline(cells: &[MatrixCell]) -> Table {
    let mut table = Table::columns(&[
        "experiment",
        "profile",
        "pacing",
        "n",
        "tracking, mm",
        "track max, mm",
        "seconds",
        "predicted, mm",
        "last reported, mm",
        "vs forecast",
        "fc path, mm",
    ]);
    for c in cells {
        table.row(vec![
            c.experiment.to_string(),
            c.profile.clone(),
            pacing_of(c).into(),
            c.completion_s.map_or(0, |i| i.n).to_string(),
            Interval::cell(c.tracking_mm, 1),
            c.tracking_error_mm
                .map_or("–".into(), |e| format!("{:.1}", e.max)),
            Interval::cell(c.completion_s, 1),
            Interval::cell(c.prediction_mm, 1),
            Interval::cell(c.stale_mm, 1),
            c.forecast_time_off
                .map_or("–".into(), |off| format!("{:.0} %", off * 100.0)),
            c.forecast_path_mm
                .map_or("–".into(), |mm| format!("{mm:.1}")),
        ]);
    }
    table
}

/// Writes report.md into `dir`, with the pictures named.
fn write(dir: &Path, m: &Matrix, pictures: &[(String, PathBuf)]) -> Result<(), CampaignError> {
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
         against it; *vs forecast*: how far the run's time was off the forecast's on the lab's \
         twin (mean of the runs), *fc path*: the mean distance between the run's path and the \
         forecast's — the sim-to-real gap, run by run.\n"
    );
    let _ = writeln!(md, "## Outcomes\n\n{}", outcomes(&m.cells).markdown());
    let _ = writeln!(
        md,
        "## Figures\n\nEach a mean over the seeds that succeeded (*n*) ± the half width of its \
         95 % confidence interval (Student's t over the seeds; none of a single seed).\n\n{}",
        headline(&m.cells).markdown()
    );
    discussion(&mut md, m);
    failed_runs(&mut md, m);
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
    let _ = writeln!(md, "{}", timing(m).markdown());
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
    super::write(&dir.join("report.md"), md)
}

/// Each profile's legs and round trips, ms.
fn timing(m: &Matrix) -> Table {
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
    t
}

/// The runs that failed, with why, if any did.
fn failed_runs(md: &mut String, m: &Matrix) {
    let failed: Vec<&MeasuredRun> = m.runs.iter().filter(|r| !r.succeeded()).collect();
    if !failed.is_empty() {
        let _ = writeln!(
            md,
            "### Runs that failed\n\nCounted in *goal* above, left out of every other figure and \
             picture:\n"
        );
        let mut t = Table::columns(&[
            "experiment",
            "profile",
            "pacing",
            "seed",
            "ended",
            "collisions",
        ]);
        for r in failed {
            t.row(vec![
                r.experiment.to_string(),
                r.profile.clone().unwrap_or_default(),
                r.pacing.to_string(),
                r.seed.to_string(),
                r.end.clone(),
                r.collisions.to_string(),
            ]);
        }
        let _ = writeln!(md, "{}", t.markdown());
    }
}

/// Where the runs agree with the thesis's claims and where they do not,
/// and why, from the figures above.
fn discussion(md: &mut String, m: &Matrix) {
    let _ = writeln!(
        md,
        "## Against the thesis: event-based and time-based control\n"
    );
    let time_lost: Vec<&MatrixCell> = m
        .cells
        .iter()
        .filter(|c| c.by_stick && c.pacing == Pacing::Time)
        .filter(|c| c.sync_violations > 0)
        .collect();
    let _ = writeln!(
        md,
        "**Synchronisation — agrees.** The thesis (§3, §7) makes event-based control keep the \
         Guest and the Host in step whatever the delay. Every event-based command here ran at \
         most one event ahead of the feedback it was sent on ({}). Time-based commands lost \
         step on {} of {} link profiles ({}).\n",
        if m.event_based_synchronised {
            "all runs"
        } else {
            "**not** all runs: see *max gap*"
        },
        time_lost.len(),
        m.profiles.len(),
        time_lost
            .iter()
            .map(|c| format!("{}: up to {} events ahead", c.profile, c.max_event_gap))
            .collect::<Vec<_>>()
            .join("; ")
    );
    let (t, event_better, time_better) = tracking_by_pacing(m);
    let _ = writeln!(md, "{}", t.markdown());
    let _ = writeln!(
        md,
        "**Tracking — {}.** The thesis expects event-based control to make teleoperation over \
         the Internet at least as good as time-based. Event-based tracked nearer the path on {} \
         ({}); time-based on {} ({}); elsewhere the seeds' spread covers the difference.\n",
        if time_better.is_empty() {
            "agrees"
        } else {
            "disagrees in part"
        },
        table::count(event_better.len() as u64, "profile", "profiles"),
        if event_better.is_empty() {
            "none".into()
        } else {
            event_better.join(", ")
        },
        table::count(time_better.len() as u64, "profile", "profiles"),
        if time_better.is_empty() {
            "none".into()
        } else {
            time_better.join(", ")
        },
    );
    let _ = writeln!(
        md,
        "**Why.** Event-based pacing sends the next command as soon as the feedback of the last \
         has come: on a short link that is more often than time-based pacing's every 20 ms, on a \
         long one once a round trip (the *commands/s* columns), while time-based pacing goes on \
         correcting every 20 ms on feedback just as old. A difference under a millimetre, as on \
         a short link, is of no weight for a robot 55 mm across. This matrix's operator \
         is a script that steers toward waypoints along the path from whatever feedback it has: \
         it turns as soon as the feedback shows it off course, so more frequent corrections keep \
         it nearer the path even when each rests on stale feedback, and where the round trip is \
         long each event-based command drives the robot for a whole round trip uncorrected. What \
         time-based pacing costs is what the thesis is about: its commands pile up ahead of the \
         feedback they were decided on (*sync lost*, *max gap*), so the Host executes commands \
         for situations already past — harmless to a script that only ever steers toward the \
         path, not to a person reacting to what they see, for whom the thesis designed the \
         scheme. The tracking figures measure the script, not that person.\n"
    );
}

/// Event- against time-based tracking per profile, with the command
/// rates behind them; and the profiles where each was nearer the path
/// beyond the seeds' spread.
fn tracking_by_pacing(m: &Matrix) -> (Table, Vec<&str>, Vec<&str>) {
    let teleop = |profile: &str, pacing: Pacing| {
        m.cells
            .iter()
            .find(|c| c.by_stick && c.pacing == pacing && c.profile == profile)
    };
    let mut t = Table::columns(&[
        "profile",
        "rtt p50, ms",
        "event tracking, mm",
        "time tracking, mm",
        "verdict",
        "event commands/s",
        "time commands/s",
    ]);
    let (mut event_better, mut time_better) = (Vec::new(), Vec::new());
    let rate = |profile: &str, pacing: Pacing| {
        Interval::of(
            m.runs
                .iter()
                .filter(|r| r.by_stick && r.pacing == pacing)
                .filter(|r| r.profile.as_deref() == Some(profile) && r.succeeded())
                .map(|r| r.commands as f64 / r.completion_s.max(1e-3)),
        )
    };
    for timing in &m.timing {
        let p = timing.profile.as_str();
        let (Some(event), Some(time)) = (teleop(p, Pacing::Event), teleop(p, Pacing::Time)) else {
            continue;
        };
        let verdict = match (event.tracking_mm, time.tracking_mm) {
            (Some(e), Some(t)) if e.apart(&t) && e.mean < t.mean => {
                event_better.push(p);
                format!("event-based nearer, by {:.1} mm", t.mean - e.mean)
            }
            (Some(e), Some(t)) if e.apart(&t) => {
                time_better.push(p);
                format!("time-based nearer, by {:.1} mm", e.mean - t.mean)
            }
            (Some(_), Some(_)) => "no difference beyond the seeds' spread".into(),
            _ => "not measured (runs failed)".into(),
        };
        t.row(vec![
            p.to_owned(),
            format!("{:.0}", timing.round_trip_p50_ms),
            Interval::cell(event.tracking_mm, 1),
            Interval::cell(time.tracking_mm, 1),
            verdict,
            Interval::cell(rate(p, Pacing::Event), 0),
            Interval::cell(rate(p, Pacing::Time), 0),
        ]);
    }
    (t, event_better, time_better)
}

impl Report for Matrix {
    fn table(&self) -> Table {
        let mut table = headline(&self.cells);
        for r in self.runs.iter().filter(|r| !r.succeeded()) {
            table = table.note(format!(
                "failed: {} on {}, {} pacing, seed {}: {} ({} collisions); left out of the figures",
                r.experiment,
                r.profile.as_deref().unwrap_or("loopback"),
                r.pacing,
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
