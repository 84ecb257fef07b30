//! The matrix's report as Markdown: its figures, the runs that failed, the
//! time analysis and the pictures.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use vl_report::table::{Report, Table, yes};

use vl_core::{Arena, Experiment};

use super::Pacing;
use super::matrix::{Matrix, MatrixCell, draw};
use super::{CampaignError, Leg, MeasuredRun};

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
        CampaignError::Draw(vl_guest::plots::PlotError {
            what: "report.json".into(),
            why: e.to_string(),
        })
    })?;
    super::write(&dir.join("report.json"), json)
}

/// The matrix's figures, a row per cell.
pub fn headline(cells: &[MatrixCell]) -> Table {
    let mut table = Table::columns(&[
        "experiment",
        "profile",
        "pacing",
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
        "vs forecast",
        "fc path",
    ]);
    let pair = |v: Option<[f64; 2]>, k: usize| v.map_or("–".into(), |v| format!("{:.1}", v[k]));
    for c in cells {
        table.row(vec![
            c.experiment.to_string(),
            c.profile.clone(),
            match (c.experiment, c.pacing) {
                (Experiment::Navigation, _) => "host".into(),
                (_, Pacing::Event) => "event".into(),
                (_, Pacing::Time) => "time".into(),
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
    let _ = writeln!(md, "## Results\n\n```\n{}```\n", headline(&m.cells));
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
    let _ = writeln!(md, "```\n{}```\n", timing(m));
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
        let _ = writeln!(md, "```\n{t}```\n");
    }
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
