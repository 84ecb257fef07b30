//! A small live view of the lab's net, in users' words: one row per part of
//! the lab (each statechart) with its states as circles and a token in the
//! one it is in, then what may happen next, marked by a green dot. The
//! controllers' monitor places are counted, not drawn: they are how the
//! rules are kept, not states a user follows. Arcs are left out: a composed
//! net has dozens.

use egui::{Color32, Sense, Stroke, Vec2};
use vl_core::Supervisor;

const ROW: f32 = 18.0;
const PLACE: f32 = 6.0;
const LABEL_WIDTH: f32 = 70.0;

/// A place's chart and state, from its name (`execute.running`), or none
/// for a controller's monitor place (`monitor: cspace.building + … <= 1`).
fn split(name: &str) -> Option<(&str, &str)> {
    if name.starts_with("monitor: ") {
        return None;
    }
    Some(name.split_once('.').unwrap_or(("", name)))
}

/// A part of the lab (a statechart) in users' words.
fn chart_words(chart: &str) -> &str {
    match chart {
        "mount" => "lab",
        "cspace" => "C-space",
        "define" => "definition",
        "execute" => "run",
        "planning" => "path",
        "following" => "robot",
        "field" => "force field",
        "teleoperation" => "robot",
        other => other,
    }
}

/// A state of a part of the lab in users' words.
fn state_words<'a>(chart: &str, state: &'a str) -> &'a str {
    match (chart, state) {
        ("mount", "idle") => "free",
        ("cspace" | "field", "absent") | ("planning", "unplanned") => "none",
        ("field", "waiting") => "waits for the C-space",
        (_, "building") => "being made",
        ("planning", "planning") => "being planned",
        ("forecast", "unpassed") => "not passed yet",
        ("define", "default") => "defaults",
        ("following", "following") => "follows the path",
        ("teleoperation", "driving") => "driven by the operator",
        (_, state) => state,
    }
}

/// An event in users' words.
pub(crate) fn event_words(event: &str) -> &str {
    match event {
        "cspace_built" => "C-space made",
        "path_planned" => "path planned",
        "forecast_passed" => "forecast passed",
        "forecast_failed" => "forecast refused",
        "field_built" => "force field made",
        "command" => "drive",
        "finish" => "run ends",
        "release" => "leave",
        other => other,
    }
}

/// A place: a circle, with a token when it is marked.
fn place(ui: &mut egui::Ui, marked: bool, ink: Color32) {
    let (rect, _) = ui.allocate_exact_size(Vec2::splat(2.0 * PLACE + 2.0), Sense::hover());
    ui.painter()
        .circle_stroke(rect.center(), PLACE, Stroke::new(1.2, ink));
    if marked {
        ui.painter().circle_filled(rect.center(), PLACE * 0.45, ink);
    }
}

/// The mounted experiment's net as `session` runs it; for one whose net
/// only the Host has (a folder this Guest does not ship), a line saying so.
pub(crate) fn show(ui: &mut egui::Ui, session: &vl_client::Session) {
    let mounted = session.lab.as_ref().map(|l| &l.experiment);
    if !session.has_net(mounted) {
        ui.label("This experiment's net is the Host's own: it allows what it enables.");
        return;
    }
    show_net(ui, &session.nets);
}

fn show_net(ui: &mut egui::Ui, nets: &Supervisor) {
    let (net, marking) = nets.marked();
    let mut rows: Vec<(&str, Vec<(&str, bool)>)> = Vec::new();
    let mut rules = 0;
    // A place fused from parallel places of several charts (its name lists
    // them) shows in each chart's row, with the same token.
    for (place, &tokens) in net.places.iter().zip(&marking.0) {
        for member in place.name.split('|') {
            let Some((chart, state)) = split(member) else {
                rules += 1;
                continue;
            };
            let (chart, state) = (chart_words(chart), state_words(chart, state));
            let marked = tokens > 0;
            match rows.iter_mut().find(|(c, _)| *c == chart) {
                Some((_, states)) => states.push((state, marked)),
                None => rows.push((chart, vec![(state, marked)])),
            }
        }
    }
    let enabled: Vec<usize> = net.enabled(marking).map(|t| t.0).collect();
    let mut events: Vec<(&str, bool)> = Vec::new();
    for (t, transition) in net.transitions.iter().enumerate() {
        let Some(event) = transition.label.as_deref() else {
            continue;
        };
        let on = enabled.contains(&t);
        let event = event_words(event);
        match events.iter_mut().find(|(e, _)| *e == event) {
            Some((_, enabled)) => *enabled |= on,
            None => events.push((event, on)),
        }
    }
    events.sort_by_key(|(e, _)| *e);
    let text = ui.visuals().text_color();
    let faint = ui.visuals().weak_text_color();
    // Each part of the lab on a line of its own, its states flowing on as
    // the panel's width allows.
    for (chart, states) in &rows {
        ui.horizontal_wrapped(|ui| {
            ui.add_sized(
                [LABEL_WIDTH, ROW],
                egui::Label::new(egui::RichText::new(*chart).color(faint)),
            );
            for (state, marked) in states {
                place(ui, *marked, text);
                ui.label(egui::RichText::new(*state).color(if *marked { text } else { faint }));
            }
        });
    }
    ui.horizontal_wrapped(|ui| {
        for (event, enabled) in &events {
            let dot = if *enabled {
                Color32::from_rgb(46, 160, 60)
            } else {
                faint.gamma_multiply(0.5)
            };
            let (rect, _) = ui.allocate_exact_size(Vec2::splat(10.0), Sense::hover());
            ui.painter().circle_filled(rect.center(), 4.0, dot);
            ui.label(egui::RichText::new(*event).color(if *enabled { text } else { faint }));
        }
    });
    // The same in words, for people who read rather than look (and for tests).
    let now: Vec<String> = rows
        .iter()
        .flat_map(|(chart, states)| {
            states
                .iter()
                .filter(|(_, marked)| *marked)
                .map(move |(state, _)| format!("{chart} {state}"))
        })
        .collect();
    let enabled: Vec<&str> = events
        .iter()
        .filter(|(_, on)| *on)
        .map(|(e, _)| *e)
        .collect();
    ui.label(format!("now: {}", now.join(", ")));
    ui.label(format!("may happen: {}", enabled.join(", ")));
    if rules > 0 {
        ui.weak(format!("{rules} rules of the lab kept by its controller"));
    }
}
