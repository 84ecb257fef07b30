//! A Guest that only watches: it follows the lab as an observer until a
//! run ends, and says what it saw.

use std::time::{Duration, Instant};

use serde::Serialize;
use vl_core::{Experiment, ExperimentId, Role, Summary};
use vl_report::table::{Table, count};

use crate::client::Connection;
use crate::headless::{RoundTripMs, Script, ScriptError, welcomed};
use crate::session::Session;

/// What an observer saw.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Watched {
    /// The experiment mounted when it left, if any.
    pub experiment: Option<ExperimentId>,
    /// How the run it saw end ended, if one did.
    pub run: Option<Summary>,
    pub feedback: u64,
    pub frames: u64,
    pub round_trip_ms: RoundTripMs,
}

/// Connects to `url` as an observer and watches until a run ends or
/// `script.timeout` passes, telling what happens on stderr when
/// `script.progress`.
pub async fn watch(url: &str, script: &Script) -> Result<Watched, ScriptError> {
    let mut guest = welcomed(url, Role::Observer, script).await?;
    let progress = script.progress;
    let mut feedback = 0u64;
    let mut last_feedback_ms = None;
    let mut shown: (Option<Experiment>, bool) = (None, false);
    let mut last_line = Instant::now();
    let on_each = |session: &mut Session, _: &Connection| {
        if let Some(robot) = &session.robot
            && last_feedback_ms != Some(robot.t_ms)
        {
            last_feedback_ms = Some(robot.t_ms);
            feedback += 1;
        }
        let now = (session.mounted().cloned(), session.running);
        if progress {
            if let Some(experiment) = now.0.as_ref().filter(|_| now.0 != shown.0) {
                eprintln!("mounted: {}", experiment.title);
            }
            if now.1 && !shown.1 {
                eprintln!("run started");
            }
            if let Some(robot) = session.robot.as_ref().filter(|_| now.1)
                && last_line.elapsed() >= Duration::from_secs(1)
            {
                last_line = Instant::now();
                eprintln!(
                    "event {:>5}  pose ({:>5.0}, {:>5.0}) mm",
                    robot.event, robot.pose.x_mm, robot.pose.y_mm
                );
            }
        }
        shown = now;
    };
    match guest.until("watch", on_each, |s| s.done.is_some()).await {
        Ok(()) | Err(ScriptError::Timeout { .. }) => {}
        Err(e) => return Err(e),
    }
    let run = guest.session.done.clone();
    if let Some(done) = run.as_ref().filter(|_| progress) {
        eprintln!(
            "run ended: {} after {:.1} s, {} events",
            done.reason, done.seconds, done.events
        );
    }
    let experiment = guest.session.lab.as_ref().map(|l| l.experiment.clone());
    let (frames, round_trip_ms) = (
        guest.session.frames_received,
        RoundTripMs::from(&guest.session.round_trips),
    );
    guest.connection.close().await;
    Ok(Watched {
        experiment,
        run,
        feedback,
        frames,
        round_trip_ms,
    })
}

impl vl_report::table::Report for Watched {
    fn table(&self) -> Table {
        let run = match &self.run {
            Some(done) => format!(
                "{} after {:.1} s, {}",
                done.ending(),
                done.seconds,
                count(done.events, "event", "events")
            ),
            None => "none ended while watching".into(),
        };
        Table::pairs([
            (
                "mounted",
                self.experiment
                    .as_ref()
                    .map_or("nothing".to_owned(), ExperimentId::to_string),
            ),
            ("run", run),
            ("feedback", self.feedback.to_string()),
            ("frames", self.frames.to_string()),
            ("round trip", self.round_trip_ms.cell()),
        ])
    }
}
