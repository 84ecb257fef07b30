//! The forecast's preview (issue 29): before Start, the definition's runs
//! on the lab's twin play over the camera view as ghosts, one per seed of
//! noise, with a slider and a play button, the verdict's figures beside
//! them, and where a refused one fails marked on the view.

use std::time::Instant;

use egui::{Color32, Pos2, Stroke, Vec2};
use vl_core::{ForecastVerdict, LabScene, Point, SeedRun};

use super::replay::time_slider;
use super::view::OnScreen;
use super::{FORECAST_COLOUR, GuestApp};

/// Where a refused forecast fails.
const REFUSED_COLOUR: Color32 = Color32::from_rgb(230, 40, 40);
const PASSED_COLOUR: Color32 = Color32::from_rgb(60, 170, 70);

/// Where the preview is in the forecast's time, and whether it plays.
#[derive(Debug, Default)]
pub(super) struct Preview {
    pub(super) t_s: f64,
    /// When play was pressed, and the time shown then.
    playing: Option<(Instant, f64)>,
}

impl Preview {
    /// Moves the time on while playing; stops at the end.
    fn advance(&mut self, longest_s: f64) {
        if let Some((since, from)) = self.playing {
            self.t_s = from + since.elapsed().as_secs_f64();
            if self.t_s >= longest_s {
                self.t_s = longest_s;
                self.playing = None;
            }
        }
    }
}

/// How long the longest seed's run lasts, s.
fn longest_s(verdict: &ForecastVerdict) -> f64 {
    verdict
        .forecast
        .runs
        .iter()
        .map(|r| r.seconds)
        .fold(0.0, f64::max)
}

/// Where `run` is `t_s` into it: between its path's points, facing along it.
fn ghost_at(run: &SeedRun, every_s: f64, t_s: f64) -> Option<(Point, Point)> {
    let last = run.path.len().checked_sub(1)?;
    let i = ((t_s / every_s.max(1e-3)).floor().max(0.0) as usize).min(last);
    let here = run.path[i];
    let ahead = run.path[(i + 1).min(last)];
    Some((here, ahead))
}

impl GuestApp {
    /// The forecast's panel: the verdict, its figures, and the player.
    pub(super) fn forecast_panel(&mut self, ui: &mut egui::Ui) {
        let Some(verdict) = &self.session.forecast else {
            self.preview = Preview::default();
            if self
                .session
                .definition
                .as_ref()
                .is_some_and(|d| !d.path.is_empty())
                && !self.session.running
            {
                ui.label("Trying the definition on the lab's twin…");
            }
            return;
        };
        let longest = longest_s(verdict);
        ui.label(egui::RichText::new("Forecast on the lab's twin").strong());
        let (colour, words) = match verdict.passed() {
            true => (PASSED_COLOUR, "Passed: the run may start.".to_owned()),
            false => (REFUSED_COLOUR, "Refused: define another.".to_owned()),
        };
        ui.colored_label(colour, words);
        for refusal in &verdict.refusals {
            ui.colored_label(REFUSED_COLOUR, format!("• {refusal}"));
        }
        // Values wrap within the panel's width rather than run off it.
        let width = ui.available_width();
        egui::Grid::new("forecast figures")
            .num_columns(2)
            .max_col_width(width * 0.6)
            .show(ui, |ui| {
                for (what, value) in verdict.figures() {
                    ui.label(what);
                    ui.add(egui::Label::new(value).wrap());
                    ui.end_row();
                }
            });
        self.preview.advance(longest);
        ui.horizontal(|ui| {
            let playing = self.preview.playing.is_some();
            if ui.button(if playing { "Pause" } else { "Play" }).clicked() {
                self.preview.playing = match playing {
                    true => None,
                    false if self.preview.t_s >= longest => Some((Instant::now(), 0.0)),
                    false => Some((Instant::now(), self.preview.t_s)),
                };
            }
            ui.add(time_slider(&mut self.preview.t_s, longest, "forecast time"));
        });
        if self.preview.playing.is_some() {
            ui.ctx().request_repaint();
        }
    }

    /// The forecast over the view: each seed's path and its ghost at the
    /// preview's time, and where a refused forecast fails. Shown until the
    /// run starts.
    pub(super) fn forecast_overlay(
        &self,
        painter: &egui::Painter,
        view: &OnScreen,
        scene: &LabScene,
    ) {
        let Some(verdict) = &self.session.forecast else {
            return;
        };
        if self.session.running {
            return;
        }
        let r = scene.robot.radius_mm as f32 * view.px_per_mm;
        let every = verdict.forecast.path_every_s;
        for run in &verdict.forecast.runs {
            let path: Vec<Pos2> = run.path.iter().map(|&p| view.to_screen(p)).collect();
            painter.line(path, Stroke::new(1.0, FORECAST_COLOUR.gamma_multiply(0.6)));
            if let Some((here, ahead)) = ghost_at(run, every, self.preview.t_s) {
                let centre = view.to_screen(here);
                painter.circle_stroke(centre, r, Stroke::new(1.5, FORECAST_COLOUR));
                let facing = (view.to_screen(ahead) - centre).normalized();
                if facing.is_finite() {
                    painter.line_segment(
                        [centre, centre + facing * r * 1.6],
                        Stroke::new(1.5, FORECAST_COLOUR),
                    );
                }
            }
        }
        for at in verdict.refusals.iter().filter_map(|r| r.at()) {
            let c = view.to_screen(at);
            let d = Vec2::splat(7.0);
            let stroke = Stroke::new(3.0, REFUSED_COLOUR);
            painter.line_segment([c - d, c + d], stroke);
            painter.line_segment([c + Vec2::new(-7.0, 7.0), c + Vec2::new(7.0, -7.0)], stroke);
            painter.circle_stroke(c, 12.0, Stroke::new(2.0, REFUSED_COLOUR));
        }
    }
}
