//! A small live view of the lab's net: one row per statechart (and one for
//! the controllers' monitor places) with its places as circles, a token in
//! each marked one, and the net's events as boxes, green while a transition
//! carrying the event is enabled. Arcs are left out: a composed net has
//! dozens, and what a user follows is which state each part of the lab is
//! in and what may happen next.

use egui::{Align2, Color32, FontId, Pos2, Sense, Stroke, Vec2};
use vl_core::Supervisor;

const ROW: f32 = 26.0;
const PLACE: f32 = 7.0;
const LABEL_WIDTH: f32 = 78.0;
const PLACE_STEP: f32 = 92.0;
const EVENT_WIDTH: f32 = 84.0;

/// A place's chart and state, from its name (`execute.running`, or a
/// controller's monitor place such as `monitor: cspace.building + … <= 1`).
fn split(name: &str) -> (&str, &str) {
    match name.strip_prefix("monitor: ") {
        Some(rule) => ("controller", rule),
        None => name.split_once('.').unwrap_or(("", name)),
    }
}

pub(crate) fn show(ui: &mut egui::Ui, nets: &Supervisor) {
    let (net, marking) = nets.marked();
    let mut rows: Vec<(&str, Vec<(&str, bool)>)> = Vec::new();
    // A place fused from parallel places of several charts (its name lists
    // them) shows in each chart's row, with the same token.
    for (place, &tokens) in net.places.iter().zip(&marking.0) {
        for member in place.name.split('|') {
            let (chart, state) = split(member);
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
        match events.iter_mut().find(|(e, _)| *e == event) {
            Some((_, enabled)) => *enabled |= on,
            None => events.push((event, on)),
        }
    }
    events.sort_by_key(|(e, _)| *e);
    let widest = rows.iter().map(|(_, s)| s.len()).max().unwrap_or(1) as f32;
    let per_row = ((ui.available_width() / EVENT_WIDTH).floor() as usize).max(1);
    let event_rows = events.len().div_ceil(per_row) as f32;
    let size = Vec2::new(
        (LABEL_WIDTH + widest * PLACE_STEP).max(ui.available_width()),
        (rows.len() as f32 + event_rows) * ROW + 8.0,
    );
    let (rect, _) = ui.allocate_exact_size(size, Sense::hover());
    let painter = ui.painter_at(rect);
    let text = ui.visuals().text_color();
    let faint = ui.visuals().weak_text_color();
    let font = FontId::proportional(11.0);
    for (i, (chart, states)) in rows.iter().enumerate() {
        let y = rect.top() + (i as f32 + 0.5) * ROW;
        painter.text(
            Pos2::new(rect.left(), y),
            Align2::LEFT_CENTER,
            chart,
            font.clone(),
            faint,
        );
        for (k, (state, marked)) in states.iter().enumerate() {
            let centre = Pos2::new(rect.left() + LABEL_WIDTH + PLACE + k as f32 * PLACE_STEP, y);
            painter.circle_stroke(centre, PLACE, Stroke::new(1.2, text));
            if *marked {
                painter.circle_filled(centre, PLACE * 0.45, text);
            }
            painter.text(
                centre + Vec2::new(PLACE + 4.0, 0.0),
                Align2::LEFT_CENTER,
                state,
                font.clone(),
                if *marked { text } else { faint },
            );
        }
    }
    let top = rect.top() + rows.len() as f32 * ROW + 4.0;
    for (i, (event, enabled)) in events.iter().enumerate() {
        let at = Pos2::new(
            rect.left() + (i % per_row) as f32 * EVENT_WIDTH,
            top + (i / per_row) as f32 * ROW,
        );
        let boxed = egui::Rect::from_min_size(at, Vec2::new(EVENT_WIDTH - 6.0, ROW - 8.0));
        let (fill, ink) = if *enabled {
            (Color32::from_rgb(46, 125, 50), Color32::WHITE)
        } else {
            (Color32::TRANSPARENT, faint)
        };
        painter.rect(
            boxed,
            3.0,
            fill,
            Stroke::new(1.0, faint),
            egui::StrokeKind::Inside,
        );
        painter.text(
            boxed.center(),
            Align2::CENTER_CENTER,
            event,
            font.clone(),
            ink,
        );
    }
    // The same in words, for people who read rather than look (and for tests).
    let marked: Vec<&str> = net
        .places
        .iter()
        .zip(&marking.0)
        .filter(|(_, n)| **n > 0)
        .map(|(p, _)| p.id.as_str())
        .collect();
    let enabled: Vec<&str> = events
        .iter()
        .filter(|(_, on)| *on)
        .map(|(e, _)| *e)
        .collect();
    ui.label(format!("marked: {}", marked.join(", ")));
    ui.label(format!("may happen: {}", enabled.join(", ")));
}
