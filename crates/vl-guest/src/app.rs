//! The desktop Guest (egui): mount, define and execute an experiment while
//! watching the camera with the robot's reported pose drawn over it, the
//! proximity readings and the live round-trip time. Click the camera view to
//! place the goal; defining it plans a path on the lab's map, which the
//! robot follows once started. Drive by hand with a mouse-dragged virtual
//! joystick or the arrow keys, which take over from the path while held.
//! The window opens whether or not the Host answers, says why when it does
//! not, and reconnects on request.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use egui::{Color32, Pos2, Rect, Sense, Stroke, TextureHandle, TextureOptions, Vec2};
use vl_core::{
    Action, Definition, DeviceState, Drive, Experiment, Goal, GuestMessage, Joystick, LOOKAHEAD_MM,
    PROTOCOL_VERSION, Point, Pose, Readiness, Role, Shape, Teleop, Vector, arena_of, disc_cspace,
};

use crate::client::{ClientError, Connection, open};
use crate::gamepad::Pad;
use crate::netview;
use crate::route::{Route, check_path, drag_path};
use crate::session::{Link, Session};
use crate::settings::{MARGIN_MM, MAX_SPEED_MM_S, Settings};
use vl_core::MountedLab;

const JOYSTICK_PX: f32 = 140.0;
const ROBOT_COLOUR: Color32 = Color32::from_rgb(40, 200, 255);
const GOAL_COLOUR: Color32 = Color32::from_rgb(40, 190, 60);
const PATH_COLOUR: Color32 = Color32::from_rgb(250, 220, 40);
const VIRTUAL_COLOUR: Color32 = Color32::from_rgb(255, 150, 0);
/// The obstacles' push, on the stick and on the robot.
const FORCE_COLOUR: Color32 = Color32::from_rgb(255, 70, 90);
/// The predictive display's ghost: where the robot is now, by prediction.
const GHOST_COLOUR: Color32 = Color32::from_rgb(235, 90, 255);
const STOP_COLOUR: Color32 = Color32::from_rgb(200, 30, 30);
/// The force arrow on the robot at full force, mm.
const FORCE_ARROW_MM: f64 = 80.0;
/// The arena drawn from its model when the lab has no camera.
const FLOOR_COLOUR: Color32 = Color32::from_rgb(226, 224, 218);
const OBSTACLE_COLOUR: Color32 = Color32::from_rgb(45, 48, 56);
/// The C-space overlay: translucent, so the image shows through.
const CSPACE_COLOUR: Color32 = Color32::from_rgba_premultiplied(60, 20, 80, 80);
/// The path the robot drove in this run.
const TRAIL_COLOUR: Color32 = Color32::from_rgb(0, 170, 150);
/// Trail points kept, and how far apart, mm.
const TRAIL_KEPT: usize = 20_000;
const TRAIL_STEP_MM: f64 = 2.0;
/// How often an idle window repaints (the ages it shows move, and a still
/// camera's noise), and one in use.
const IDLE_REPAINT: Duration = Duration::from_secs(1);
const BUSY_REPAINT: Duration = Duration::from_millis(30);

/// Who the window connects to, and as whom.
#[derive(Debug, Clone)]
struct Address {
    url: String,
    role: Role,
    token: Option<String>,
}

/// The Guest's window.
pub struct GuestApp {
    address: Address,
    session: Session,
    connection: Connection,
    texture: Option<(u64, TextureHandle)>,
    /// Virtual joystick deflection: x = turn right, y = forward, each in −1..1.
    joystick: Vec2,
    goal: Goal,
    /// What planning the defined goal gave: the path's length, or why none.
    plan_note: Option<String>,
    /// What the user tuned, and where it is kept between sessions (none:
    /// not kept).
    settings: Settings,
    settings_file: Option<PathBuf>,
    /// Obstacles drawn on the view (thesis F.2), for the next definition.
    virtual_obstacles: Vec<Shape>,
    /// Drags on the view draw virtual obstacles instead of placing the goal.
    drawing: bool,
    /// Where the drag drawing an obstacle began, floor mm.
    drag_from: Option<Point>,
    /// The defined path's sample being dragged (thesis F.4).
    dragging_sample: Option<usize>,
    /// Whether the C-space is shown over the view, and its cells as boxes
    /// for the map and obstacles they were grown from.
    show_cspace: bool,
    cspace: Option<(CSpaceKey, Vec<Shape>)>,
    /// Draw the predictive display's ghost (thesis C.1).
    show_ghost: bool,
    /// The one joystick → velocity mapping, as the Host reads it back.
    teleop: Teleop,
    /// A real stick, when there is one, and whether its stop button was down.
    pad: Option<(Box<dyn Pad>, bool)>,
    /// The stick that drove in the last frame, from whichever device.
    asked: Joystick,
    /// Where the robot went in the run under way or the last, as reported.
    trail: Vec<Point>,
    /// The session's welcomes this window has caught up with.
    welcomes: u64,
}

impl GuestApp {
    /// A window on the Host at `url`, connecting as `role` straight away
    /// (on the current tokio runtime). Only an address that cannot be a
    /// Host's is refused; an unreachable Host is shown in the window.
    pub fn new(url: &str, role: Role, token: Option<String>) -> Result<Self, ClientError> {
        let address = Address {
            url: url.to_owned(),
            role,
            token,
        };
        let connection = GuestApp::connect(&address)?;
        Ok(GuestApp {
            address,
            session: Session::default(),
            connection,
            texture: None,
            joystick: Vec2::ZERO,
            goal: Goal::at(Point::default()),
            plan_note: None,
            settings: Settings::default(),
            settings_file: None,
            virtual_obstacles: Vec::new(),
            drawing: false,
            drag_from: None,
            dragging_sample: None,
            show_cspace: false,
            cspace: None,
            show_ghost: true,
            teleop: Teleop::default(),
            pad: None,
            asked: Joystick::default(),
            trail: Vec::new(),
            welcomes: 0,
        })
    }

    /// The window with the settings kept in `file` (loaded now, saved on
    /// every change).
    pub fn with_settings_file(mut self, file: PathBuf) -> Self {
        self.settings = Settings::load(&file);
        self.settings_file = Some(file);
        self
    }

    /// The window with a real stick beside the virtual one.
    pub fn with_pad(mut self, pad: Box<dyn Pad>) -> Self {
        self.pad = Some((pad, false));
        self
    }

    /// Opens a connection that says hello as soon as it is up.
    fn connect(address: &Address) -> Result<Connection, ClientError> {
        let connection = open(&address.url)?;
        connection.send(GuestMessage::Hello {
            protocol: PROTOCOL_VERSION,
            role: address.role,
            token: address.token.clone(),
            resume: None,
        });
        Ok(connection)
    }

    /// Starts over on a new connection: what the old one knew is gone.
    fn reconnect(&mut self) {
        self.session = Session::default();
        self.forget_the_host();
        match GuestApp::connect(&self.address) {
            Ok(connection) => self.connection = connection,
            Err(e) => self.session.link = Link::Closed(e.to_string()),
        }
    }

    /// The session as the window knows it.
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// Draws the whole window into `ui`.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        self.pump();
        let ctx = ui.ctx().clone();
        self.drive(&ctx);
        egui::Panel::top("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::left("controls")
            .default_size(270.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        if self.session.is_operator() {
            egui::Panel::bottom("joystick").show(ui, |ui| self.joystick(ui));
        } else if self.session.role.is_some() {
            egui::Panel::bottom("watching").show(ui, |ui| {
                ui.label(
                    "You are watching: only the operator drives. STOP (Space) is for everyone.",
                );
            });
        }
        if self.session.lab.is_some() || self.session.frame.is_some() {
            egui::Panel::bottom("view legend").show(ui, |ui| self.view_legend(ui));
        }
        egui::CentralPanel::default().show(ui, |ui| self.camera_view(ui));
        // Repaint when something moves; an idle window only keeps its
        // ages current (input repaints at once by itself).
        let moving = self
            .session
            .robot
            .as_ref()
            .is_some_and(|r| r.wheels.left_mm_s.abs().max(r.wheels.right_mm_s.abs()) > 0.5);
        let busy = self.session.running
            || !self.session.ready()
            || moving
            || self.asked != Joystick::default();
        ctx.request_repaint_after(if busy { BUSY_REPAINT } else { IDLE_REPAINT });
    }

    /// Takes in everything that arrived since the last frame.
    fn pump(&mut self) {
        let was_mounted = self.session.lab.clone();
        let was_running = self.session.running;
        while let Some(incoming) = self.connection.try_recv() {
            self.session.apply(incoming);
        }
        self.session.decode_frame();
        if self.session.welcomes != self.welcomes {
            // A new connection, perhaps to a Host started again.
            self.welcomes = self.session.welcomes;
            self.forget_the_host();
        }
        if let Some(lab) = &self.session.lab
            && Some(lab) != was_mounted.as_ref()
        {
            // Another experiment: nothing of the last one's stays on screen.
            self.plan_note = None;
            self.trail.clear();
            self.dragging_sample = None;
            if let Some(goal) = lab.arena.goal {
                self.goal.x_mm = goal.x_mm;
                self.goal.y_mm = goal.y_mm;
            }
        }
        if self.session.running && !was_running && self.session.done.is_none() {
            self.trail.clear();
        }
        if let Some(robot) = self.session.robot.as_ref().filter(|_| self.session.running) {
            let p = robot.pose.point();
            if self.trail.len() < TRAIL_KEPT
                && self
                    .trail
                    .last()
                    .is_none_or(|q| q.distance(p) >= TRAIL_STEP_MM)
            {
                self.trail.push(p);
            }
        }
    }

    /// Forgets what the window drew from a Host's word.
    fn forget_the_host(&mut self) {
        self.texture = None;
        self.plan_note = None;
        self.cspace = None;
        self.dragging_sample = None;
        self.drag_from = None;
        self.trail.clear();
    }

    /// Sends the next event-paced command: from the joystick or arrow keys
    /// while they are in use, otherwise along the defined path. Space and
    /// Esc are the emergency stop.
    fn drive(&mut self, ctx: &egui::Context) {
        let typing = ctx.memory(|m| m.focused().is_some());
        let stop = ctx.input(|i| {
            i.key_pressed(egui::Key::Escape) || (!typing && i.key_pressed(egui::Key::Space))
        });
        let pad = self.pad.as_mut().map(|(pad, was_down)| {
            let input = pad.poll();
            let pressed = input.emergency_stop && !*was_down;
            *was_down = input.emergency_stop;
            let force = self.session.robot.as_ref().and_then(|r| r.force);
            pad.render(force.unwrap_or_default());
            (input, pressed)
        });
        if stop || pad.is_some_and(|(_, pressed)| pressed) {
            self.emergency_stop();
        }
        if !self.session.is_operator() {
            return;
        }
        let by_pad = pad.map(|(input, _)| input.drive()).unwrap_or_default();
        let stick = if by_pad != Joystick::default() {
            by_pad
        } else {
            self.stick(ctx)
        };
        self.asked = stick;
        let by_hand = stick != Joystick::default();
        let Some(lab) = &self.session.lab else { return };
        // The Host follows a defined path by itself; the stick, while
        // held, takes over from it.
        if self.session.host_follows() && !by_hand {
            return;
        }
        let asked = self.teleop.desired(stick);
        let drive = Drive::from(self.teleop.wheels(&lab.robot, asked));
        if let Some(command) = self.session.next_command(drive, Instant::now()) {
            self.connection.send(command);
        }
    }

    /// Where the stick is: the dragged virtual stick plus the arrow keys,
    /// x to the right and y forward, each within −1..1.
    fn stick(&self, ctx: &egui::Context) -> Joystick {
        let (mut forward, mut turn) = (f64::from(self.joystick.y), f64::from(self.joystick.x));
        ctx.input(|i| {
            let key = |k| if i.key_down(k) { 1.0 } else { 0.0 };
            forward += key(egui::Key::ArrowUp) - key(egui::Key::ArrowDown);
            turn += key(egui::Key::ArrowRight) - key(egui::Key::ArrowLeft);
        });
        Joystick {
            x: turn.clamp(-1.0, 1.0),
            y: forward.clamp(-1.0, 1.0),
        }
    }

    /// Asks the Host to stop the robot now and end the run.
    fn emergency_stop(&mut self) {
        self.joystick = Vec2::ZERO;
        self.connection.send(GuestMessage::EmergencyStop);
    }

    /// What the robot is doing, as a stick position: its measured wheel
    /// speeds through the inverse of the stick's mapping.
    fn doing(&self) -> Option<Vec2> {
        let (robot, lab) = (self.session.robot.as_ref()?, self.session.lab.as_ref()?);
        let w = robot.wheels;
        let v = (w.left_mm_s + w.right_mm_s) / 2.0;
        let turn = (w.right_mm_s - w.left_mm_s) / lab.robot.wheel_base_mm;
        let Vector { x, y } = self.teleop.velocity_for(&lab.robot, v, turn);
        let top = self.teleop.max_speed_mm_s;
        Some(Vec2::new((-y / top) as f32, (x / top) as f32))
    }

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        let mut reconnect = false;
        let mut stop = false;
        let s = &self.session;
        // One line, whatever the width: the link's state gives way (cut
        // short, whole on hover) to the STOP button and the figures.
        ui.horizontal(|ui| {
            let button = egui::Button::new(
                egui::RichText::new("STOP (Space)")
                    .strong()
                    .color(Color32::WHITE),
            )
            .fill(STOP_COLOUR);
            stop = ui
                .add_enabled(s.link == Link::Open, button)
                .on_hover_text("Emergency stop: the robot stops and the run ends (Space or Esc)")
                .clicked();
            if matches!(s.link, Link::Closed(_)) {
                reconnect = ui.button("Reconnect").clicked();
            }
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                let acknowledged = s.robot.as_ref().map_or(0, |r| r.event);
                ui.label(format!("event {acknowledged} (sent {})", s.sent_event));
                ui.separator();
                let rtt = &s.round_trips;
                ui.label(match rtt.last() {
                    Some(last) => format!(
                        "RTT {last:.1} ms (p99 {:.1})",
                        rtt.quantile(0.99).unwrap_or(last)
                    ),
                    None => "RTT –".into(),
                });
                ui.separator();
                ui.with_layout(egui::Layout::left_to_right(egui::Align::Center), |ui| {
                    let line = self.status_line();
                    let full = line.text.clone();
                    ui.add(egui::Label::new(line).truncate())
                        .on_hover_text(full);
                });
            });
        });
        if reconnect {
            self.reconnect();
        }
        if stop {
            self.emergency_stop();
        }
    }

    /// The link's state, who this Guest is, and what of the lab is not
    /// as it should be, coloured by how much it matters.
    fn status_line(&self) -> egui::text::LayoutJob {
        let s = &self.session;
        let mut job = egui::text::LayoutJob::default();
        let mut add = |text: &str, colour: Color32| {
            if !job.text.is_empty() {
                job.append(" · ", 0.0, egui::TextFormat::default());
            }
            job.append(
                text,
                0.0,
                egui::TextFormat {
                    color: colour,
                    ..Default::default()
                },
            );
        };
        match &s.link {
            Link::Connecting => add(
                &format!("connecting to {}…", self.address.url),
                Color32::YELLOW,
            ),
            Link::Unreachable { attempt, reason } => add(
                &format!("{reason} — trying again (attempt {attempt})"),
                Color32::YELLOW,
            ),
            Link::Open => add("connected", Color32::GREEN),
            Link::Reconnecting { attempt, reason } => add(
                &format!("link lost ({reason}): reconnecting, attempt {attempt}…"),
                Color32::YELLOW,
            ),
            Link::Closed(why) => add(&format!("not connected: {why}"), Color32::RED),
        }
        if let (Some(role), Some(id)) = (s.role, s.session_id) {
            add(&format!("{role}, session {id}"), Color32::GRAY);
        }
        if let Some(devices) = s.devices {
            if devices.robot == DeviceState::Offline {
                add("robot offline: the Host is retrying", Color32::RED);
            }
            if devices.camera == DeviceState::Offline {
                add("camera offline", Color32::YELLOW);
            }
            if devices.lab == Readiness::GettingReady {
                add("lab getting ready", Color32::YELLOW);
            }
        }
        if let Some((pad, _)) = &self.pad {
            add(&format!("stick: {}", pad.name()), Color32::GRAY);
        }
        job
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("Mount");
        for experiment in self.session.experiments.clone() {
            let mounted = self
                .session
                .lab
                .as_ref()
                .is_some_and(|l| l.experiment == experiment.id);
            let button = egui::Button::new(&experiment.title).selected(mounted);
            if ui
                .add_enabled(self.session.allows(Action::Mount), button)
                .clicked()
            {
                self.connection.send(GuestMessage::Mount {
                    experiment: experiment.id.to_string(),
                });
            }
        }
        if let Some(lab) = self.session.lab.clone() {
            ui.separator();
            if self.session.is_operator() {
                self.define_panel(ui, lab.experiment);
            } else {
                ui.heading("Definition");
                ui.label(
                    match self.session.definition.as_ref().and_then(|d| d.goal) {
                        Some(goal) => format!(
                            "the operator's goal: ({:.0}, {:.0}) mm",
                            goal.x_mm, goal.y_mm
                        ),
                        None => "the operator has defined nothing yet".into(),
                    },
                );
            }
            ui.separator();
            ui.heading("Execute");
            if self.session.is_operator() {
                self.execute_buttons(ui);
            }
            if !self.session.ready() {
                ui.colored_label(
                    Color32::YELLOW,
                    "Getting ready: the robot drives back to its start pose.",
                );
            }
            if let Some(done) = &self.session.done {
                let goal = match (lab.experiment, done.reached_goal) {
                    (_, true) => ", goal reached",
                    (Experiment::Navigation, false) => ", goal not reached",
                    (Experiment::Teleoperation, false) => "",
                };
                ui.label(format!(
                    "Last run: {}{goal} after {:.1} s, {:.0} mm driven, {} contacts.",
                    done.reason, done.seconds, done.distance_mm, done.collisions
                ));
                if let Some(why) = done.held_back {
                    ui.label(format!("Why: {why}."));
                }
                if let Some(who) = done.stopped_by {
                    ui.label(format!("The emergency stop was pressed by {who}."));
                }
            }
        }
        if self.session.role.is_some() {
            ui.separator();
            egui::CollapsingHeader::new("Lab net")
                .default_open(false)
                .show(ui, |ui| netview::show(ui, &self.session.nets));
        }
        if let Some(robot) = &self.session.robot {
            ui.separator();
            ui.heading("Robot");
            ui.label(format!(
                "pose ({:.0}, {:.0}) mm, {:.0}°",
                robot.pose.x_mm,
                robot.pose.y_mm,
                robot.pose.theta_rad.to_degrees()
            ));
            ui.label(format!(
                "wheels {:.0} / {:.0} mm/s{}",
                robot.wheels.left_mm_s,
                robot.wheels.right_mm_s,
                if robot.contact { " · CONTACT" } else { "" }
            ));
            ui.label("proximity");
            for (i, &value) in robot.proximity.iter().enumerate() {
                ui.add(
                    egui::ProgressBar::new(f32::from(value) / 1023.0)
                        .text(format!("IR{i} {value}"))
                        .desired_height(12.0),
                );
            }
        }
        if !self.session.errors.is_empty() {
            ui.separator();
            ui.heading("Host said");
            for (_, message) in self.session.errors.iter().rev() {
                ui.colored_label(Color32::LIGHT_RED, message);
            }
        }
    }

    /// The operator's definition: the goal (and in navigation the path
    /// planned to it), virtual obstacles, the settings.
    fn define_panel(&mut self, ui: &mut egui::Ui, experiment: Experiment) {
        ui.heading("Define");
        ui.label(match experiment {
            Experiment::Navigation => {
                "Click the view for a goal; Define plans the path the robot follows."
            }
            Experiment::Teleoperation => "Click the view for a target to drive to (optional).",
        });
        ui.horizontal(|ui| {
            ui.label("goal x");
            ui.add(egui::DragValue::new(&mut self.goal.x_mm).suffix(" mm"));
            ui.label("y");
            ui.add(egui::DragValue::new(&mut self.goal.y_mm).suffix(" mm"));
        });
        ui.horizontal(|ui| {
            ui.label("within");
            ui.add(
                egui::DragValue::new(&mut self.goal.tolerance_mm)
                    .range(1.0..=200.0)
                    .suffix(" mm"),
            );
            if ui
                .add_enabled(
                    self.session.allows(Action::Define),
                    egui::Button::new("Define"),
                )
                .clicked()
            {
                self.define();
            }
        });
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.drawing, "draw obstacles")
                .on_hover_text(
                    "drag on the view to draw a virtual obstacle the robot must keep out of",
                );
            let drawn = self.virtual_obstacles.len();
            if drawn > 0 {
                ui.label(format!("{drawn} drawn"));
                if ui.button("Clear").clicked() {
                    self.virtual_obstacles.clear();
                }
            }
        });
        if let Some(note) = &self.plan_note {
            ui.label(note);
        }
        self.settings_panel(ui);
    }

    /// Start, Stop, and the drive back to the start pose.
    fn execute_buttons(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            // Defining is optional: a run may start on the defaults.
            if ui
                .add_enabled(
                    self.session.allows(Action::Start),
                    egui::Button::new("Start"),
                )
                .clicked()
            {
                self.connection.send(GuestMessage::Start);
            }
            if ui
                .add_enabled(self.session.allows(Action::Stop), egui::Button::new("Stop"))
                .clicked()
            {
                self.connection.send(GuestMessage::Stop);
            }
            let between_runs = !self.session.nets.allows(Action::Stop) && self.session.ready();
            if ui
                .add_enabled(between_runs, egui::Button::new("Back to start"))
                .on_hover_text(
                    "the robot drives back to the lab's start pose, as it does after every run",
                )
                .clicked()
            {
                self.connection.send(GuestMessage::Reset);
            }
        });
    }

    /// Plans a path from the robot to the goal on the lab's map and defines
    /// both. Navigation needs the path; in teleoperation, without one, the
    /// goal alone is defined as a target to drive to by hand.
    fn define(&mut self) {
        let Some(lab) = &self.session.lab else { return };
        let start = self
            .session
            .robot
            .as_ref()
            .map_or(lab.arena.start, |r| r.pose);
        let obstacles = self.virtual_obstacles.clone();
        let definition = match Route::plan(lab, start, self.goal, obstacles.clone(), &self.settings)
        {
            Ok(route) => {
                self.plan_note = Some(format!(
                    "path {:.0} mm; the body keeps {:.0} mm from obstacles",
                    route.plan.length_mm,
                    route.body_clearance_mm(lab)
                ));
                route.definition
            }
            Err(e) if lab.experiment == Experiment::Navigation => {
                self.plan_note = Some(format!(
                    "Not defined: no path to the goal ({e}). Move the goal, or clear the obstacles drawn."
                ));
                return;
            }
            Err(e) => {
                self.plan_note = Some(format!("no path ({e}): drive there by hand"));
                Definition {
                    goal: Some(self.goal),
                    virtual_obstacles: obstacles,
                    max_speed_mm_s: self.settings.max_speed_mm_s,
                    ..Definition::default()
                }
            }
        };
        self.connection.send(GuestMessage::Define { definition });
    }

    fn joystick(&mut self, ui: &mut egui::Ui) {
        // Smaller in a small window, so the view keeps the room.
        let size = JOYSTICK_PX.min(ui.ctx().content_rect().height() * 0.2);
        ui.horizontal(|ui| {
            let (response, painter) = ui.allocate_painter(Vec2::splat(size), Sense::drag());
            let centre = response.rect.center();
            let radius = size / 2.0 - 4.0;
            if let Some(pointer) = response.interact_pointer_pos().filter(|_| response.dragged()) {
                let offset = (pointer - centre) / radius;
                let offset = if offset.length() > 1.0 { offset.normalized() } else { offset };
                self.joystick = Vec2::new(offset.x, -offset.y);
            } else {
                self.joystick = Vec2::ZERO;
            }
            painter.circle_stroke(centre, radius, Stroke::new(2.0, Color32::GRAY));
            // Screen y runs down; the stick's y is forward.
            let on_pad = |v: Vec2| centre + Vec2::new(v.x, -v.y) * radius;
            if let Some(doing) = self.doing() {
                painter.circle_stroke(on_pad(doing), 10.0, Stroke::new(2.0, Color32::WHITE));
            }
            let asked = self.asked;
            painter.circle_filled(
                on_pad(Vec2::new(asked.x as f32, asked.y as f32)),
                14.0,
                ROBOT_COLOUR,
            );
            let force = self.session.robot.as_ref().and_then(|r| r.force);
            if let Some([fx, fy]) = force.filter(|f| f[0].hypot(f[1]) > 0.02) {
                let tip = on_pad(Vec2::new(fx as f32, fy as f32));
                painter.arrow(centre, tip - centre, Stroke::new(4.0, FORCE_COLOUR));
            }
            ui.vertical(|ui| {
                ui.label("Drag the stick or hold the arrow keys to drive\n(commands flow while a run is started).");
                ui.label("Filled: what you ask. Ring: what the robot does.");
                if force.is_some() {
                    ui.label("Red arrow: the obstacles' push you would feel.");
                }
                if self.session.robot.as_ref().is_some_and(|r| r.limited) {
                    ui.colored_label(Color32::YELLOW, "The Host's safety layer is holding the robot back.");
                }
            });
        });
    }

    /// The camera image with what the Guest knows drawn over it; without a
    /// camera, the arena as its model describes it.
    fn camera_view(&mut self, ui: &mut egui::Ui) {
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
                        let texture =
                            ui.ctx()
                                .load_texture("camera", image, TextureOptions::NEAREST);
                        self.texture = Some((seq, texture));
                    }
                }
            }
        }
        let image_size = match (&self.texture, &self.session.lab) {
            (Some((_, texture)), _) => texture.size_vec2(),
            (None, Some(lab)) => Vec2::new(lab.camera.width_px as f32, lab.camera.height_px as f32),
            (None, None) => {
                let waiting = match &self.session.link {
                    Link::Connecting => "connecting to the Host…",
                    Link::Unreachable { .. } => "no Host answers yet: trying again…",
                    Link::Reconnecting { .. } => "reconnecting to the Host…",
                    Link::Open => "mount an experiment to see the lab",
                    Link::Closed(_) => "not connected to a Host",
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
        let on_floor = |pos: Pos2, lab: &MountedLab| {
            let col = (pos.x - rect.min.x) / rect.width() * lab.camera.width_px as f32;
            let row = (pos.y - rect.min.y) / rect.height() * lab.camera.height_px as f32;
            lab.camera.to_arena(f64::from(col), f64::from(row))
        };
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
                    self.dragging_sample = self.sample_near(origin, &View::new(rect, lab));
                }
                if response.drag_stopped()
                    && let Some(index) = self.dragging_sample.take()
                {
                    self.edit_path(index, p);
                } else if response.clicked() {
                    // A click on the floor places the goal there.
                    (self.goal.x_mm, self.goal.y_mm) = (p.x_mm.round(), p.y_mm.round());
                }
            }
        }
        let painter = ui.painter_at(rect);
        match (&self.texture, &self.session.lab) {
            (Some((_, texture)), _) => {
                painter.image(
                    texture.id(),
                    rect,
                    Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
                    Color32::WHITE,
                );
            }
            (None, Some(lab)) => {
                painter.rect_filled(rect, 0.0, FLOOR_COLOUR);
                let view = View::new(rect, lab);
                for obstacle in &lab.arena.obstacles {
                    view.fill(&painter, &obstacle.shape, OBSTACLE_COLOUR);
                }
            }
            (None, None) => {}
        }
        if let Some(lab) = self.session.lab.clone() {
            let view = View::new(rect, &lab);
            if self.show_cspace {
                // One mesh of the cells' quads, edge to edge: no seams where
                // outlines or anti-aliased edges would overlap.
                let mut mesh = egui::Mesh::default();
                for cell in self.cspace_boxes(&lab) {
                    let corners = view.outline_of(cell);
                    let first = mesh.vertices.len() as u32;
                    for &corner in &corners {
                        mesh.colored_vertex(corner, CSPACE_COLOUR);
                    }
                    for k in 1..corners.len().saturating_sub(1) as u32 {
                        mesh.add_triangle(first, first + k, first + k + 1);
                    }
                }
                painter.add(mesh);
            }
            if self.trail.len() > 1 {
                let line: Vec<Pos2> = self.trail.iter().map(|&p| view.to_screen(p)).collect();
                painter.line(line, Stroke::new(1.5, TRAIL_COLOUR));
            }
            self.overlay(&painter, &view, &lab);
            for obstacle in &self.virtual_obstacles {
                view.outline(
                    &painter,
                    obstacle,
                    Stroke::new(1.5, VIRTUAL_COLOUR.gamma_multiply(0.7)),
                );
            }
            if let (Some(from), Some(pos)) = (self.drag_from, response.interact_pointer_pos())
                && let Some(shape) = drawn_box(from, on_floor(pos, &lab))
            {
                view.outline(&painter, &shape, Stroke::new(1.5, VIRTUAL_COLOUR));
            }
            // The path as it would be bent, while a sample is dragged.
            if let (Some(index), Some(pos), Some(definition)) = (
                self.dragging_sample,
                response.interact_pointer_pos(),
                &self.session.definition,
            ) && let Ok(bent) = drag_path(&definition.path, index, on_floor(pos, &lab))
            {
                let line: Vec<Pos2> = bent.iter().map(|&p| view.to_screen(p)).collect();
                painter.line(line, Stroke::new(1.5, PATH_COLOUR.gamma_multiply(0.6)));
            }
        }
    }

    /// Under the view: what is overlaid, what its colours mean, and how
    /// old what is shown is.
    fn view_legend(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.show_cspace, "C-space")
                .on_hover_text("where the robot's centre may not go: the map and the virtual obstacles grown by its radius");
            ui.checkbox(&mut self.show_ghost, "predictive display")
                .on_hover_text("a ghost of the robot where it is now, predicted from the last feedback and the commands sent since; the solid outline is where the last feedback put it");
        });
        ui.horizontal_wrapped(|ui| {
            legend(ui, ROBOT_COLOUR, "robot, as last reported");
            if self.show_ghost {
                legend(ui, GHOST_COLOUR, "ghost: where it is now, predicted");
            }
            legend(ui, TRAIL_COLOUR, "driven");
            legend(ui, PATH_COLOUR, "path");
            legend(ui, GOAL_COLOUR, "goal");
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

    /// The settings the next definition takes (thesis F.6), kept on change.
    fn settings_panel(&mut self, ui: &mut egui::Ui) {
        let before = self.settings;
        egui::CollapsingHeader::new("Settings").show(ui, |ui| {
            let s = &mut self.settings;
            ui.horizontal(|ui| {
                ui.label("look-ahead");
                ui.add(
                    egui::DragValue::new(&mut s.lookahead_mm)
                        .range(LOOKAHEAD_MM)
                        .suffix(" mm"),
                );
            });
            ui.horizontal(|ui| {
                ui.label("margin");
                ui.add(
                    egui::DragValue::new(&mut s.margin_mm)
                        .range(MARGIN_MM)
                        .suffix(" mm"),
                );
            });
            ui.horizontal(|ui| {
                let mut limited = s.max_speed_mm_s.is_some();
                ui.checkbox(&mut limited, "speed limit");
                let mut v = s.max_speed_mm_s.unwrap_or(200.0);
                ui.add_enabled(
                    limited,
                    egui::DragValue::new(&mut v)
                        .range(MAX_SPEED_MM_S)
                        .suffix(" mm/s"),
                );
                s.max_speed_mm_s = limited.then_some(v);
            });
        });
        if self.settings != before
            && let Some(file) = &self.settings_file
            && let Err(e) = self.settings.save(file)
        {
            self.plan_note = Some(e.to_string());
        }
    }

    /// The defined path's sample nearest `pos` on screen, if within reach
    /// of the pointer.
    fn sample_near(&self, pos: Pos2, view: &View) -> Option<usize> {
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
            arena: lab.arena.clone(),
            virtual_obstacles: self.virtual_obstacles.clone(),
        };
        if self.cspace.as_ref().is_none_or(|(k, _)| *k != key) {
            let boxes = match disc_cspace(&lab.arena, &self.virtual_obstacles, lab.robot.radius_mm)
            {
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

    fn overlay(&self, painter: &egui::Painter, view: &View, lab: &MountedLab) {
        let to_screen = |p: Point| view.to_screen(p);
        let px_per_mm = view.px_per_mm;
        // The goal being chosen, before it is defined (the operator's only).
        if self.session.is_operator() {
            painter.circle_stroke(
                to_screen(self.goal.point()),
                4.0,
                Stroke::new(1.5, GOAL_COLOUR.gamma_multiply(0.7)),
            );
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
        }
        if let Some(robot) = &self.session.robot {
            let centre = to_screen(robot.pose.point());
            let r = lab.robot.radius_mm as f32 * px_per_mm;
            painter.circle_stroke(centre, r, Stroke::new(2.0, ROBOT_COLOUR));
            let nose = to_screen(robot.pose.to_world(lab.robot.radius_mm * 1.6, 0.0));
            painter.line_segment([centre, nose], Stroke::new(2.0, ROBOT_COLOUR));
            if let Some(tip) = robot.force.and_then(|f| force_tip(robot.pose, f)) {
                painter.arrow(
                    centre,
                    to_screen(tip) - centre,
                    Stroke::new(3.0, FORCE_COLOUR),
                );
            }
            if self.show_ghost
                && let Some(ghost) = self.session.predicted(Instant::now())
                // On the reported pose, it would hide it.
                && ghost.point().distance(robot.pose.point()) >= 1.0
            {
                let at = to_screen(ghost.point());
                // An outline only: the camera's image of the robot stays visible.
                painter.circle_stroke(at, r, Stroke::new(2.0, GHOST_COLOUR));
                let nose = to_screen(ghost.to_world(lab.robot.radius_mm * 1.6, 0.0));
                painter.line_segment([at, nose], Stroke::new(1.5, GHOST_COLOUR));
                painter.line_segment([centre, at], Stroke::new(1.0, GHOST_COLOUR));
            }
        }
    }
}

/// A colour swatch and what it stands for, in the view's legend.
fn legend(ui: &mut egui::Ui, colour: Color32, what: &str) {
    let (rect, _) = ui.allocate_exact_size(Vec2::new(14.0, 4.0), Sense::hover());
    ui.painter().rect_filled(rect, 1.0, colour);
    ui.label(what);
}

/// The accessible name of the camera view, by which tests find it.
pub const CAMERA_VIEW: &str = "camera view";
/// How near the pointer must be to a path sample to grab it, px.
const GRAB_PX: f32 = 10.0;

/// What a C-space overlay was computed from.
#[derive(Debug, Clone, PartialEq)]
struct CSpaceKey {
    arena: vl_core::Arena,
    virtual_obstacles: Vec<Shape>,
}

/// The smallest virtual obstacle a drag draws, mm a side: anything smaller
/// was a click.
const MIN_DRAWN_MM: f64 = 5.0;

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
struct View<'a> {
    rect: Rect,
    lab: &'a MountedLab,
    px_per_mm: f32,
}

impl<'a> View<'a> {
    fn new(rect: Rect, lab: &'a MountedLab) -> View<'a> {
        // Lengths drawn as circles (the robot, the goal) take the scale at
        // the image's centre.
        let px_per_mm = rect.width() / (lab.camera.width_px as f32 * lab.camera.mm_per_px() as f32);
        View {
            rect,
            lab,
            px_per_mm,
        }
    }

    fn to_screen(&self, p: Point) -> Pos2 {
        let camera = &self.lab.camera;
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

impl eframe::App for GuestApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

/// Opens the Guest window on the Host at `url` and runs it until it is
/// closed. Needs a tokio runtime entered, alive on another thread, for the
/// connection.
pub fn run_window(
    url: &str,
    role: Role,
    token: Option<String>,
    pad: Option<Box<dyn Pad>>,
) -> Result<(), WindowError> {
    let mut app = GuestApp::new(url, role, token)?;
    if let Some(file) = Settings::default_path() {
        app = app.with_settings_file(file);
    }
    if let Some(pad) = pad {
        app = app.with_pad(pad);
    }
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("vl guest")
            .with_inner_size([1100.0, 720.0]),
        ..Default::default()
    };
    eframe::run_native("vl guest", options, Box::new(move |_cc| Ok(Box::new(app))))
        .map_err(|e| WindowError::Window(e.to_string()))
}

/// Why the window did not run.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    #[error(transparent)]
    Address(#[from] ClientError),
    #[error("the Guest window failed: {0}")]
    Window(String),
}
