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

/// The speeds a replay plays at.
const SPEEDS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];

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

    /// The run's results, at the side of the window (beside the camera
    /// view, not over it) while they are asked for.
    pub fn results_panel(&self, ui: &mut egui::Ui) {
        if !self.show_results {
            return;
        }
        // A third of the window at most: the camera view keeps the most.
        let width = (ui.available_width() * 0.3).clamp(200.0, 420.0);
        egui::Panel::right("results")
            .default_size(width)
            .max_size(width)
            .show(ui, |ui| {
                ui.heading("Results");
                egui::ScrollArea::vertical().show(ui, |ui| self.results.show(ui, self.at_s));
            });
    }

    /// The replay's controls: play or pause, the time slider, the speed.
    pub fn controls(&mut self, ui: &mut egui::Ui) {
        // Wrapped, so a narrow window keeps every control in view; the
        // file's name here, its whole path on hover.
        ui.horizontal_wrapped(|ui| {
            let name = Path::new(&self.file)
                .file_name()
                .map_or_else(|| self.file.clone(), |n| n.to_string_lossy().into_owned());
            ui.label(format!("Replay of {name}"))
                .on_hover_text(&self.file);
            let play = if self.playing { "Pause" } else { "Play" };
            if ui.button(play).clicked() {
                if !self.playing && self.at_s >= self.duration_s {
                    self.at_s = 0.0;
                }
                self.playing = !self.playing;
            }
            let mut at = self.at_s;
            if ui
                .add(time_slider(&mut at, self.duration_s, "time"))
                .changed()
            {
                self.seek(at);
            }
            egui::ComboBox::from_label("speed")
                .selected_text(format!("{}×", self.speed))
                .show_ui(ui, |ui| {
                    for speed in SPEEDS {
                        ui.selectable_value(&mut self.speed, speed, format!("{speed}×"));
                    }
                });
            ui.toggle_value(&mut self.show_results, "Results");
        });
    }
}

/// A slider over a span of time from 0 to `end_s`, shown to a tenth of a
/// second but not rounded to one (as `fixed_decimals` would): a run of
/// 4.73 s must reach its last moment, where its end is.
pub(crate) fn time_slider<'a>(t_s: &'a mut f64, end_s: f64, text: &str) -> egui::Slider<'a> {
    egui::Slider::new(t_s, 0.0..=end_s.max(0.001))
        .custom_formatter(|t, _| format!("{t:.1}"))
        .suffix(" s")
        .text(text)
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

#[cfg(test)]
mod tests {
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;

    use super::time_slider;

    /// Dragged to its end, the slider gives the span's very end, not the
    /// tenth below it.
    #[test]
    fn the_time_slider_reaches_a_span_end_between_tenths() {
        for end_s in [4.73, 4.71, 0.04, 12.349] {
            let mut harness = Harness::new_ui_state(
                |ui, t_s: &mut f64| {
                    ui.add(time_slider(t_s, end_s, "time"));
                },
                0.0,
            );
            let rail = harness
                .get_by_role_and_label(egui::accesskit::Role::Slider, "time")
                .rect();
            let from = rail.center();
            harness.hover_at(from);
            harness.step();
            harness.drag_at(from);
            harness.step();
            harness.hover_at(egui::pos2(rail.right() + 20.0, from.y));
            harness.step();
            harness.drop_at(egui::pos2(rail.right() + 20.0, from.y));
            harness.step();
            assert_eq!(*harness.state(), end_s, "dragged to the end of {end_s} s");
        }
    }
}
