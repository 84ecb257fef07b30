//! The camera view: the frame (or the arena drawn from its model), with the
//! robot's pose, trail, ghost, path, goal, C-space and force drawn over
//! it, and the clicks and drags that edit the definition on it.

use egui::{Color32, Pos2, Rect, Sense, Stroke, TextureOptions, Vec2};
use vl_core::{
    Definition, GuestMessage, LabScene, Mark, MountedLab, Point, Pose, Shape, arena_of, disc_cspace,
};

use std::time::Instant;

use super::{
    CAMERA_VIEW, CSPACE_COLOUR, CSpaceKey, FLOOR_COLOUR, FORCE_ARROW_MM, FORCE_COLOUR,
    GHOST_COLOUR, GOAL_COLOUR, GuestApp, OBSTACLE_COLOUR, PATH_COLOUR, ROBOT_COLOUR, TRAIL_COLOUR,
    VIRTUAL_COLOUR, colour,
};
use vl_client::LinkState;
use vl_client::{check_path, drag_path};

/// How near the pointer must be to a path sample to grab it, px.
const GRAB_PX: f32 = 10.0;

/// The smallest virtual obstacle a drag draws, mm a side: anything smaller
/// was a click.
const MIN_DRAWN_MM: f64 = 5.0;

impl GuestApp {
    /// The camera image with what the Guest knows drawn over it; without a
    /// camera, the arena as its model describes it.
    pub(super) fn camera_view(&mut self, ui: &mut egui::Ui) {
        self.take_frame(ui.ctx());
        let image_size = match (&self.texture, self.session.scene()) {
            (Some((_, texture)), _) => texture.size_vec2(),
            (None, Some(scene)) => {
                Vec2::new(scene.camera.width_px as f32, scene.camera.height_px as f32)
            }
            (None, None) => {
                let waiting = match &self.session.link {
                    LinkState::Connecting if !self.session.errors.is_empty() => {
                        "the Host has not let you in: see what it said, on the left"
                    }
                    LinkState::Connecting => "connecting to the Host…",
                    LinkState::Unreachable { .. } => "no Host answers yet: trying again…",
                    LinkState::Reconnecting { .. } => "reconnecting to the Host…",
                    LinkState::Open => "mount an experiment to see the lab",
                    LinkState::Closed(_) => "not connected to a Host",
                };
                ui.centered_and_justified(|ui| ui.label(waiting));
                return;
            }
        };
        let available = ui.available_size();
        let scale = (available.x / image_size.x)
            .min(available.y / image_size.y)
            .max(0.1);
        let (rect, response) = ui.allocate_exact_size(image_size * scale, Sense::click_and_drag());
        response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, CAMERA_VIEW));
        let on_floor = |pos: Pos2, scene: &LabScene| on_floor(rect, pos, scene);
        self.interact(ui, &response, rect);
        let painter = ui.painter_at(rect);
        match (&self.texture, self.session.scene()) {
            (Some((_, texture)), _) => {
                painter.image(
                    texture.id(),
                    rect,
                    Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
                    Color32::WHITE,
                );
            }
            (None, Some(scene)) => {
                painter.rect_filled(rect, 0.0, FLOOR_COLOUR);
                let view = OnScreen::new(rect, scene);
                for obstacle in &scene.arena.obstacles {
                    view.fill(&painter, &obstacle.shape, OBSTACLE_COLOUR);
                }
            }
            (None, None) => {}
        }
        // Before a mount too: the welcome told the floor, the robot and the camera.
        if let Some(scene) = self.session.scene().cloned() {
            let view = OnScreen::new(rect, &scene);
            if let (true, Some(lab)) = (self.show_cspace, self.session.lab.clone()) {
                painter.add(self.cspace_mesh(&view, &lab));
            }
            if self.trail.len() > 1 {
                let line: Vec<Pos2> = self.trail.iter().map(|&p| view.to_screen(p)).collect();
                painter.line(line, Stroke::new(1.5, TRAIL_COLOUR));
            }
            self.overlay(&painter, &view, &scene);
            for obstacle in &self.virtual_obstacles {
                view.outline(
                    &painter,
                    obstacle,
                    Stroke::new(1.5, VIRTUAL_COLOUR.gamma_multiply(0.7)),
                );
            }
            if let (Some(from), Some(pos)) = (self.drag_from, response.interact_pointer_pos())
                && let Some(shape) = drawn_box(from, on_floor(pos, &scene))
            {
                view.outline(&painter, &shape, Stroke::new(1.5, VIRTUAL_COLOUR));
            }
            // The path as it would be bent, while a sample is dragged.
            if let (Some(index), Some(pos), Some(definition)) = (
                self.dragging_sample,
                response.interact_pointer_pos(),
                &self.session.definition,
            ) && let Ok(bent) = drag_path(&definition.path, index, on_floor(pos, &scene))
            {
                let line: Vec<Pos2> = bent.iter().map(|&p| view.to_screen(p)).collect();
                painter.line(line, Stroke::new(1.5, PATH_COLOUR.gamma_multiply(0.6)));
            }
        }
    }

    /// Takes the newest camera frame into the view's texture.
    fn take_frame(&mut self, ctx: &egui::Context) {
        if let Some(frame) = &self.session.frame {
            let seq = frame.header.seq;
            if self.texture.as_ref().is_none_or(|(shown, _)| *shown != seq) {
                let size = [frame.image.width() as usize, frame.image.height() as usize];
                let image = egui::ColorImage::from_rgba_unmultiplied(size, frame.image.as_raw());
                match &mut self.texture {
                    Some((shown, texture)) => {
                        texture.set(image, TextureOptions::NEAREST);
                        *shown = seq;
                    }
                    None => {
                        let texture = ctx.load_texture("camera", image, TextureOptions::NEAREST);
                        self.texture = Some((seq, texture));
                    }
                }
            }
        }
    }

    /// What a click or drag on the view does: draws a virtual obstacle,
    /// bends the path, or places the goal.
    fn interact(&mut self, ui: &egui::Ui, response: &egui::Response, rect: Rect) {
        let on_floor = |pos: Pos2, lab: &MountedLab| on_floor(rect, pos, &lab.scene);
        if let (Some(pos), Some(lab)) = (response.interact_pointer_pos(), &self.session.lab) {
            let p = on_floor(pos, lab);
            // A drag is seen to start only once the pointer has moved a
            // little: it starts where the button went down.
            let origin = ui.input(|i| i.pointer.press_origin()).unwrap_or(pos);
            if self.drawing {
                // A drag draws a box between where it began and where it ends.
                if response.drag_started() {
                    self.drag_from = Some(on_floor(origin, lab));
                }
                if response.drag_stopped()
                    && let Some(from) = self.drag_from.take()
                    && let Some(shape) = drawn_box(from, p)
                {
                    self.virtual_obstacles.push(shape);
                }
            } else if !self.session.running && self.session.is_operator() {
                if response.drag_started() {
                    // A drag that starts on the defined path bends it.
                    self.dragging_sample =
                        self.sample_near(origin, &OnScreen::new(rect, &lab.scene));
                }
                if response.drag_stopped()
                    && let Some(index) = self.dragging_sample.take()
                {
                    self.edit_path(index, p);
                } else if response.clicked() {
                    let p = Point {
                        x_mm: p.x_mm.round(),
                        y_mm: p.y_mm.round(),
                    };
                    match self.waypoint_bounds() {
                        // A click adds the next point to visit, up to the most.
                        Some((_, max)) if self.waypoints.len() < max => self.waypoints.push(p),
                        Some(_) => {}
                        // A click on the floor places the goal there.
                        None => (self.goal.x_mm, self.goal.y_mm) = (p.x_mm, p.y_mm),
                    }
                }
            }
        }
    }

    /// The C-space's cells as one mesh of quads, edge to edge: no seams
    /// where outlines or anti-aliased edges would overlap.
    fn cspace_mesh(&mut self, view: &OnScreen, lab: &MountedLab) -> egui::Mesh {
        let mut mesh = egui::Mesh::default();
        for cell in self.cspace_boxes(lab) {
            let corners = view.outline_of(cell);
            let first = mesh.vertices.len() as u32;
            for &corner in &corners {
                mesh.colored_vertex(corner, CSPACE_COLOUR);
            }
            for k in 1..corners.len().saturating_sub(1) as u32 {
                mesh.add_triangle(first, first + k, first + k + 1);
            }
        }
        mesh
    }

    /// Under the view: what is overlaid, what its colours mean, and how
    /// old what is shown is.
    pub(super) fn view_legend(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.show_cspace, "C-space")
                .on_hover_text("where the robot's centre may not go: the map and the virtual obstacles grown by its radius");
            if self.replay.is_none() {
                ui.checkbox(&mut self.show_ghost, "predictive display")
                    .on_hover_text("a ghost of the robot where it is now, predicted from the last feedback and the commands sent since; the solid outline is where the last feedback put it");
            }
        });
        ui.horizontal_wrapped(|ui| {
            let mut mark = |mark: Mark| legend(ui, colour(mark), mark.words());
            mark(Mark::Robot);
            if self.show_ghost && self.replay.is_none() {
                mark(Mark::Ghost);
            }
            mark(Mark::Trail);
            mark(Mark::Path);
            if self.session.forecast.is_some() && !self.session.running {
                mark(Mark::Forecast);
            }
            mark(Mark::Goal);
        });
        ui.label(self.ages());
        ui.label(match &self.session.frame {
            Some(frame) => format!(
                "frame {} · event {} · captured at {:.2} s",
                frame.header.seq,
                frame.header.event,
                frame.header.capture_us as f64 / 1e6
            ),
            None => "no camera in this lab: the arena as its map describes it".into(),
        });
    }

    /// The defined path's sample nearest `pos` on screen, if within reach
    /// of the pointer.
    fn sample_near(&self, pos: Pos2, view: &OnScreen) -> Option<usize> {
        let path = &self.session.definition.as_ref()?.path;
        path.iter()
            .enumerate()
            .map(|(i, &p)| (i, view.to_screen(p).distance(pos)))
            .filter(|&(_, d)| d <= GRAB_PX)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    /// Moves the defined path's sample `index` to `to`, bending the path
    /// around it, and defines the result if the robot can follow it.
    fn edit_path(&mut self, index: usize, to: Point) {
        let (Some(lab), Some(definition)) = (&self.session.lab, &self.session.definition) else {
            return;
        };
        let checked = drag_path(&definition.path, index, to)
            .and_then(|path| check_path(lab, &definition.virtual_obstacles, &path).map(|()| path));
        match checked {
            Ok(path) => {
                self.plan_note = Some("the changed path is clear: defined".into());
                let definition = Definition {
                    path,
                    ..definition.clone()
                };
                self.connection.send(GuestMessage::Define { definition });
            }
            Err(why) => self.plan_note = Some(format!("not changed: {why}")),
        }
    }

    /// The C-space of the mounted map and the virtual obstacles, as boxes,
    /// computed again only when either changes.
    fn cspace_boxes(&mut self, lab: &MountedLab) -> &[Shape] {
        let key = CSpaceKey {
            arena: lab.scene.arena.clone(),
            virtual_obstacles: self.virtual_obstacles.clone(),
        };
        if self.cspace.as_ref().is_none_or(|(k, _)| *k != key) {
            let boxes = match disc_cspace(
                &lab.scene.arena,
                &self.virtual_obstacles,
                lab.scene.robot.radius_mm,
            ) {
                Ok(cspace) => arena_of(cspace.grid(), "cspace", None)
                    .obstacles
                    .into_iter()
                    .map(|o| o.shape)
                    .collect(),
                Err(e) => {
                    tracing::warn!("no C-space to show: {e}");
                    Vec::new()
                }
            };
            self.cspace = Some((key, boxes));
        }
        self.cspace.as_ref().map_or(&[], |(_, boxes)| boxes)
    }

    /// Draws what the Guest knows over the camera image: the robot's
    /// reported pose, the goal, the planned path and the virtual obstacles.
    /// How old what the window shows is (since it arrived, plus the
    /// one-way delay it travelled: half the round trip), and how far ahead
    /// the ghost is.
    fn ages(&self) -> String {
        // A recording is as old as the replay makes it: no wall clock, no
        // prediction (the Guest's commands are not in it).
        if let Some(replay) = &self.replay {
            return format!(
                "replay at {:.1} s of {:.1} s: the pose and the frame as recorded then",
                replay.at_s, replay.duration_s
            );
        }
        let now = Instant::now();
        let travelled = self.session.predictor.one_way();
        let age = |at: Option<Instant>| {
            at.map_or("–".to_owned(), |t| {
                let old = now.saturating_duration_since(t) + travelled;
                format!("{:.2} s", old.as_secs_f64())
            })
        };
        // A frame is as old as the pose plus how much earlier (on the
        // Host's clock) it was captured than the pose was measured.
        let frame_old = match (
            &self.session.robot,
            &self.session.frame,
            self.session.feedback_at,
        ) {
            (Some(robot), Some(frame), Some(at)) => {
                let earlier_s = (robot.t_ms - frame.header.capture_us as f64 / 1e3).max(0.0) / 1e3;
                let old = now.saturating_duration_since(at) + travelled;
                format!("{:.2} s", old.as_secs_f64() + earlier_s)
            }
            _ => age(self.session.frame_at),
        };
        let mut text = format!(
            "pose {} old · frame {frame_old} old",
            age(self.session.feedback_at)
        );
        if let (true, Some(ghost), Some(robot)) = (
            self.show_ghost,
            self.session.predicted(now),
            &self.session.robot,
        ) {
            text += &format!(
                " · ghost {:.0} mm from the reported pose",
                ghost.point().distance(robot.pose.point())
            );
        }
        text
    }

    fn overlay(&self, painter: &egui::Painter, view: &OnScreen, scene: &LabScene) {
        let to_screen = |p: Point| view.to_screen(p);
        let px_per_mm = view.px_per_mm;
        // The goal or the waypoints being chosen, before they are defined
        // (the operator's only).
        if self.session.is_operator() && self.waypoint_bounds().is_none() {
            painter.circle_stroke(
                to_screen(self.goal.point()),
                4.0,
                Stroke::new(1.5, GOAL_COLOUR.gamma_multiply(0.7)),
            );
        }
        if self.session.is_operator() {
            waypoint_marks(painter, &self.waypoints, to_screen, 0.7);
        }
        if let Some(definition) = &self.session.definition {
            let path: Vec<Pos2> = definition.path.iter().map(|&p| to_screen(p)).collect();
            painter.line(path, Stroke::new(2.0, PATH_COLOUR));
            if let Some(goal) = definition.goal {
                let centre = to_screen(goal.point());
                let r = (goal.tolerance_mm as f32 * px_per_mm).max(4.0);
                painter.circle_stroke(centre, r, Stroke::new(2.0, GOAL_COLOUR));
                painter.line_segment(
                    [centre - Vec2::splat(r), centre + Vec2::splat(r)],
                    Stroke::new(2.0, GOAL_COLOUR),
                );
                painter.line_segment(
                    [centre + Vec2::new(-r, r), centre + Vec2::new(r, -r)],
                    Stroke::new(2.0, GOAL_COLOUR),
                );
            }
            for obstacle in &definition.virtual_obstacles {
                view.outline(painter, obstacle, Stroke::new(2.0, VIRTUAL_COLOUR));
            }
            waypoint_marks(painter, &definition.waypoints, to_screen, 1.0);
        }
        self.forecast_overlay(painter, view, scene);
        if let Some(robot) = &self.session.robot {
            let centre = to_screen(robot.pose.point());
            let r = scene.robot.radius_mm as f32 * px_per_mm;
            painter.circle_stroke(centre, r, Stroke::new(2.0, ROBOT_COLOUR));
            let nose = to_screen(robot.pose.to_world(scene.robot.radius_mm * 1.6, 0.0));
            painter.line_segment([centre, nose], Stroke::new(2.0, ROBOT_COLOUR));
            if let Some(tip) = robot.force.and_then(|f| force_tip(robot.pose, f)) {
                painter.arrow(
                    centre,
                    to_screen(tip) - centre,
                    Stroke::new(3.0, FORCE_COLOUR),
                );
            }
            if self.show_ghost
                && self.replay.is_none()
                && let Some(ghost) = self.session.predicted(Instant::now())
                // On the reported pose, it would hide it.
                && ghost.point().distance(robot.pose.point()) >= 1.0
            {
                let at = to_screen(ghost.point());
                // An outline only: the camera's image of the robot stays visible.
                painter.circle_stroke(at, r, Stroke::new(2.0, GHOST_COLOUR));
                let nose = to_screen(ghost.to_world(scene.robot.radius_mm * 1.6, 0.0));
                painter.line_segment([at, nose], Stroke::new(1.5, GHOST_COLOUR));
                painter.line_segment([centre, at], Stroke::new(1.0, GHOST_COLOUR));
            }
        }
    }
}

/// Each of `waypoints` as a ring with its number, in the goal's colour
/// (fainter, `alpha` < 1, while only chosen).
fn waypoint_marks(
    painter: &egui::Painter,
    waypoints: &[Point],
    to_screen: impl Fn(Point) -> Pos2,
    alpha: f32,
) {
    let colour = GOAL_COLOUR.gamma_multiply(alpha);
    for (i, &p) in waypoints.iter().enumerate() {
        let at = to_screen(p);
        painter.circle_stroke(at, 7.0, Stroke::new(2.0, colour));
        painter.text(
            at + Vec2::new(9.0, -9.0),
            egui::Align2::LEFT_BOTTOM,
            (i + 1).to_string(),
            egui::FontId::proportional(13.0),
            colour,
        );
    }
}

/// A colour swatch and what it stands for, in the view's legend.
fn legend(ui: &mut egui::Ui, colour: Color32, what: &str) {
    let (rect, _) = ui.allocate_exact_size(Vec2::new(14.0, 4.0), Sense::hover());
    ui.painter().rect_filled(rect, 1.0, colour);
    ui.label(what);
}

/// The box a drag from `a` to `b` draws, if it is big enough to mean one.
fn drawn_box(a: Point, b: Point) -> Option<Shape> {
    let (w, h) = ((a.x_mm - b.x_mm).abs(), (a.y_mm - b.y_mm).abs());
    (w >= MIN_DRAWN_MM && h >= MIN_DRAWN_MM).then(|| Shape::Rect {
        x_mm: a.x_mm.min(b.x_mm).round(),
        y_mm: a.y_mm.min(b.y_mm).round(),
        width_mm: w.round(),
        height_mm: h.round(),
    })
}

/// Where the force arrow drawn on the robot at `pose` ends: the force is in
/// joystick axes (x to the robot's right, y ahead); none when it is too
/// weak to see.
fn force_tip(pose: Pose, [right, ahead]: [f64; 2]) -> Option<Point> {
    (right.hypot(ahead) > 0.02)
        .then(|| pose.to_world(ahead * FORCE_ARROW_MM, -right * FORCE_ARROW_MM))
}

/// Where the arena lands on screen: the camera model's pixels scaled into
/// the view's rectangle.
pub(super) struct OnScreen<'a> {
    rect: Rect,
    scene: &'a LabScene,
    pub(super) px_per_mm: f32,
}

impl<'a> OnScreen<'a> {
    fn new(rect: Rect, scene: &'a LabScene) -> OnScreen<'a> {
        // Lengths drawn as circles (the robot, the goal) take the scale at
        // the image's centre.
        let px_per_mm =
            rect.width() / (scene.camera.width_px as f32 * scene.camera.mm_per_px() as f32);
        OnScreen {
            rect,
            scene,
            px_per_mm,
        }
    }

    pub(super) fn to_screen(&self, p: Point) -> Pos2 {
        let camera = &self.scene.camera;
        let (c, r) = camera.to_pixel(p);
        self.rect.min
            + Vec2::new(
                c as f32 / camera.width_px as f32 * self.rect.width(),
                r as f32 / camera.height_px as f32 * self.rect.height(),
            )
    }

    /// The screen outline of `shape`. Through a tilted camera a box is a
    /// quadrilateral and a circle an ellipse, so both are drawn as the
    /// image of their outline.
    fn outline_of(&self, shape: &Shape) -> Vec<Pos2> {
        match *shape {
            Shape::Rect { .. } => {
                let (lo, hi) = shape.bounds();
                [
                    (lo.x_mm, lo.y_mm),
                    (hi.x_mm, lo.y_mm),
                    (hi.x_mm, hi.y_mm),
                    (lo.x_mm, hi.y_mm),
                ]
                .map(|(x_mm, y_mm)| self.to_screen(Point { x_mm, y_mm }))
                .to_vec()
            }
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => (0..32)
                .map(|i| {
                    let a = f64::from(i) * std::f64::consts::TAU / 32.0;
                    self.to_screen(Point {
                        x_mm: x_mm + radius_mm * a.cos(),
                        y_mm: y_mm + radius_mm * a.sin(),
                    })
                })
                .collect(),
            Shape::Polygon { ref points } => points.iter().map(|&p| self.to_screen(p)).collect(),
        }
    }

    fn outline(&self, painter: &egui::Painter, shape: &Shape, stroke: Stroke) {
        let mut corners = self.outline_of(shape);
        corners.extend(corners.first().copied());
        painter.line(corners, stroke);
    }

    /// egui fills convex outlines; arena polygons are checked simple, and a
    /// concave one still shows its outline.
    fn fill(&self, painter: &egui::Painter, shape: &Shape, colour: Color32) {
        painter.add(egui::Shape::convex_polygon(
            self.outline_of(shape),
            colour,
            Stroke::new(1.0, colour),
        ));
    }
}

/// The point on the floor under `pos` in the view `rect`.
fn on_floor(rect: Rect, pos: Pos2, scene: &LabScene) -> Point {
    let col = (pos.x - rect.min.x) / rect.width() * scene.camera.width_px as f32;
    let row = (pos.y - rect.min.y) / rect.height() * scene.camera.height_px as f32;
    scene.camera.to_arena(f64::from(col), f64::from(row))
}
