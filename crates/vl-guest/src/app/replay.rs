//! A replay in the window: its controls, and the run's results plotted
//! beside the camera view.

use std::path::Path;

use egui_plot::{Legend, Line, Plot, PlotPoints, Points, VLine};
use vl_client::{Replay, Results, Series};
use vl_core::Mark;

use super::colour;

/// The speeds a replay plays at.
const SPEEDS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];

/// The run's results, at the side of the window (beside the camera
/// view, not over it) while they are asked for.
pub(crate) fn results_panel(replay: &Replay, ui: &mut egui::Ui) {
    if !replay.show_results {
        return;
    }
    // A third of the window at most: the camera view keeps the most.
    let width = (ui.available_width() * 0.3).clamp(200.0, 420.0);
    egui::Panel::right("results")
        .default_size(width)
        .max_size(width)
        .show(ui, |ui| {
            ui.heading("Results");
            egui::ScrollArea::vertical().show(ui, |ui| results(&replay.results, ui, replay.at_s));
        });
}

/// The replay's controls: play or pause, the time slider, the speed.
pub(crate) fn controls(replay: &mut Replay, ui: &mut egui::Ui) {
    // Wrapped, so a narrow window keeps every control in view; the
    // file's name here, its whole path on hover.
    ui.horizontal_wrapped(|ui| {
        let name = Path::new(&replay.file)
            .file_name()
            .map_or_else(|| replay.file.clone(), |n| n.to_string_lossy().into_owned());
        ui.label(format!("Replay of {name}"))
            .on_hover_text(&replay.file);
        let play = if replay.playing { "Pause" } else { "Play" };
        if ui.button(play).clicked() {
            if !replay.playing && replay.at_s >= replay.duration_s {
                replay.at_s = 0.0;
            }
            replay.playing = !replay.playing;
        }
        let mut at = replay.at_s;
        if ui
            .add(time_slider(&mut at, replay.duration_s, "time"))
            .changed()
        {
            replay.seek(at);
        }
        egui::ComboBox::from_label("speed")
            .selected_text(format!("{}×", replay.speed))
            .show_ui(ui, |ui| {
                for speed in SPEEDS {
                    ui.selectable_value(&mut replay.speed, speed, format!("{speed}×"));
                }
            });
        ui.toggle_value(&mut replay.show_results, "Results");
    });
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

/// The plots, with the replay's time `at_s` marked on those over time.
pub(crate) fn results(results: &Results, ui: &mut egui::Ui, at_s: f64) {
    let line = |name: &str, series: &Series| Line::new(name, PlotPoints::from(series.clone()));
    ui.label("the floor, mm");
    Plot::new("paths")
        .height(220.0)
        .data_aspect(1.0)
        .legend(Legend::default())
        .show(ui, |plot| {
            for (i, run) in results.forecast.iter().enumerate() {
                let name = if i == 0 { "forecast" } else { "" };
                plot.line(line(name, run).color(colour(Mark::Forecast)));
            }
            plot.line(line("planned", &results.planned).color(colour(Mark::Path)));
            plot.line(line("followed", &results.followed).color(colour(Mark::Robot)));
        });
    let over_time = |ui: &mut egui::Ui, id: &str, title: &str, series: &[(&str, &Series)]| {
        ui.label(title);
        let mut plot = Plot::new(id).height(110.0);
        // One series is named by the title: a legend would only cover it.
        if series.len() > 1 {
            plot = plot.legend(Legend::default().background_alpha(0.6));
        }
        plot.show(ui, |plot| {
            for (name, s) in series {
                plot.line(line(name, s));
            }
            plot.vline(VLine::new("now", at_s));
        });
    };
    over_time(
        ui,
        "tracking",
        "off the planned path, mm, against s",
        &[("error", &results.tracking_error_mm)],
    );
    over_time(
        ui,
        "wheels",
        "wheel speeds, mm/s, against s",
        &[("left", &results.left_mm_s), ("right", &results.right_mm_s)],
    );
    if !results.force.is_empty() {
        over_time(
            ui,
            "force",
            "force fed back, against s",
            &[("force", &results.force)],
        );
    }
    // Pinged every 200 ms: points, not a line between them.
    ui.label("round trip, ms, against s");
    Plot::new("rtt").height(110.0).show(ui, |plot| {
        plot.points(
            Points::new(
                "round trip",
                PlotPoints::from(results.round_trip_ms.clone()),
            )
            .radius(2.5),
        );
        plot.vline(VLine::new("now", at_s));
    });
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
