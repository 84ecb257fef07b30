//! A recorded run played back through the same `Session` (and, in the
//! window, the same camera view) as a live one: the Guest sees what its
//! Guests saw, in time, with a slider to scrub, pause and a speed.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;
use vl_core::{Feedback, FrameHeader, HostMessage, Point, Role, Summary};
use vl_record::{RecordError, Recording, Replayed};
use vl_report::table::{Report, Table};

use crate::client::Incoming;
use crate::results::Results;
use crate::session::Session;

/// A recorded run and where its playback is.
pub struct Replay {
    pub file: String,
    /// What the Guests got, with its time from the recording's start, s.
    items: Vec<(f64, Incoming)>,
    pub duration_s: f64,
    /// The time shown, s, and how many items the session has taken.
    pub at_s: f64,
    applied: usize,
    pub playing: bool,
    pub speed: f64,
    last_tick: Option<Instant>,
    /// The run's results, and whether they are shown.
    pub results: Results,
    pub show_results: bool,
}

impl Replay {
    pub fn open(path: &Path) -> Result<Replay, RecordError> {
        let recording = Recording::open(path)?;
        let replayed = recording.replay()?;
        let start = replayed.first().map_or(0, |(ns, _)| *ns);
        let since_start = |ns: u64| ns.saturating_sub(start) as f64 * 1e-9;
        let round_trips = recording
            .round_trips()
            .into_iter()
            .map(|(ns, ms)| [since_start(ns), ms])
            .collect();
        let items: Vec<(f64, Incoming)> = replayed
            .into_iter()
            .filter_map(|(ns, item)| {
                let incoming = match item {
                    Replayed::Message(m) => Incoming::Message(Box::new(m)),
                    Replayed::Frame(wire) => {
                        let (header, image) = FrameHeader::decode(&wire).ok()?;
                        Incoming::Frame(header, image.to_vec())
                    }
                };
                Some((since_start(ns), incoming))
            })
            .collect();
        Ok(Replay {
            results: Results::of(&items, round_trips),
            show_results: false,
            file: path.display().to_string(),
            duration_s: items.last().map_or(0.0, |(t, _)| *t),
            items,
            at_s: 0.0,
            applied: 0,
            playing: true,
            speed: 1.0,
            last_tick: None,
        })
    }

    /// A session as a watcher's: welcomed as an observer of the lab.
    fn fresh() -> Session {
        let mut session = Session::default();
        session.apply(Incoming::Message(Box::new(HostMessage::Welcome {
            session: 0,
            role: Role::Observer,
            experiments: Vec::new(),
            resume: None,
            user: None,
            scene: None,
        })));
        session
    }

    /// Moves to `t_s` (clamped to the run).
    pub fn seek(&mut self, t_s: f64) {
        self.at_s = t_s.clamp(0.0, self.duration_s);
    }

    /// Where the robot was reported, from the run's start to the replay's
    /// time, a point every `step_mm`.
    pub fn trail(&self, step_mm: f64) -> Vec<Point> {
        let mut trail: Vec<Point> = Vec::new();
        for (_, incoming) in &self.items[..self.applied] {
            let Incoming::Message(message) = incoming else {
                continue;
            };
            match **message {
                HostMessage::Started { .. } => trail.clear(),
                HostMessage::Feedback(Feedback { pose, .. }) => {
                    let p = pose.point();
                    if trail.last().is_none_or(|q| q.distance(p) >= step_mm) {
                        trail.push(p);
                    }
                }
                _ => {}
            }
        }
        trail
    }

    /// Feeds `session` what came up to the replay's time, after moving it
    /// on by the time since the last call when playing; a step back starts
    /// the session over.
    pub fn advance(&mut self, session: &mut Session) {
        let now = Instant::now();
        if self.playing
            && let Some(last) = self.last_tick
        {
            self.seek(self.at_s + (now - last).as_secs_f64() * self.speed);
            if self.at_s >= self.duration_s {
                self.playing = false;
            }
        }
        self.last_tick = Some(now);
        let behind = self
            .applied
            .checked_sub(1)
            .is_some_and(|i| self.items[i].0 > self.at_s);
        if behind || self.applied == 0 {
            *session = Replay::fresh();
            self.applied = 0;
        }
        while let Some((t, incoming)) = self.items.get(self.applied) {
            if *t > self.at_s {
                break;
            }
            session.apply(incoming.clone());
            self.applied += 1;
        }
    }
}

/// What a replay to the end showed.
#[derive(Debug, Clone, Serialize)]
pub struct ReplayReport {
    pub file: String,
    pub seconds: f64,
    pub feedback: usize,
    pub frames: u64,
    /// The summary the replayed session ended with.
    pub summary: Option<Summary>,
}

/// Plays `path` to its end through a session, as a headless Guest.
pub fn replay_headless(path: &Path) -> Result<ReplayReport, RecordError> {
    let mut replay = Replay::open(path)?;
    let feedback = replay
        .items
        .iter()
        .filter(
            |(_, i)| matches!(i, Incoming::Message(m) if matches!(**m, HostMessage::Feedback(_))),
        )
        .count();
    let mut session = Session::default();
    replay.seek(replay.duration_s);
    replay.playing = false;
    replay.advance(&mut session);
    Ok(ReplayReport {
        file: replay.file,
        seconds: replay.duration_s,
        feedback,
        frames: session.frames_received,
        summary: session.done,
    })
}

impl Report for ReplayReport {
    fn table(&self) -> Table {
        let ending = self
            .summary
            .as_ref()
            .map_or_else(|| "no end recorded".to_owned(), Summary::ending);
        let mut rows = vec![
            ("file", self.file.clone()),
            ("recorded", format!("{:.1} s", self.seconds)),
            ("feedback", self.feedback.to_string()),
            ("frames", self.frames.to_string()),
            ("ending", ending),
        ];
        if let Some(s) = &self.summary {
            rows.push((
                "reached goal",
                if s.reached_goal { "yes" } else { "no" }.to_owned(),
            ));
            rows.push((
                "run",
                format!("{:.1} s, {:.0} mm driven", s.seconds, s.distance_mm),
            ));
        }
        Table::pairs(rows).title("replayed")
    }
}
