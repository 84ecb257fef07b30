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

use egui::{Color32, TextureHandle, Vec2};
use vl_core::{
    DeviceState, Drive, ErrorCode, Goal, GuestMessage, Joystick, Mark, Point, Readiness, Role,
    Shape, Teleop, Vector,
};

use crate::gamepad::Pad;
use vl_client::GOODBYE_WAIT;
use vl_client::Login;
use vl_client::Settings;
use vl_client::{ClientError, Connection, Incoming, open};
use vl_client::{LinkState, Session};

mod controller;
mod panels;
mod preview;
mod recordings;
mod replay;
mod tasks;
mod view;

const JOYSTICK_PX: f32 = 140.0;

/// A mark's colour in the shared legend (the page draws with the same).
pub(crate) const fn colour(mark: Mark) -> Color32 {
    let [r, g, b] = mark.rgb();
    Color32::from_rgb(r, g, b)
}

const ROBOT_COLOUR: Color32 = colour(Mark::Robot);
const GOAL_COLOUR: Color32 = colour(Mark::Goal);
const PATH_COLOUR: Color32 = colour(Mark::Path);
const VIRTUAL_COLOUR: Color32 = colour(Mark::VirtualObstacle);
/// The obstacles' push, on the stick and on the robot.
const FORCE_COLOUR: Color32 = colour(Mark::Force);
/// The predictive display's ghost: where the robot is now, by prediction.
const GHOST_COLOUR: Color32 = colour(Mark::Ghost);
/// The forecast's ghosts and paths: the definition's runs on the lab's twin.
const FORECAST_COLOUR: Color32 = colour(Mark::Forecast);
const STOP_COLOUR: Color32 = Color32::from_rgb(200, 30, 30);
/// The force arrow on the robot at full force, mm.
const FORCE_ARROW_MM: f64 = 80.0;
/// The arena drawn from its model when the lab has no camera.
const FLOOR_COLOUR: Color32 = colour(Mark::Floor);
const OBSTACLE_COLOUR: Color32 = colour(Mark::Obstacle);
/// The C-space overlay: translucent, so the image shows through.
const CSPACE_COLOUR: Color32 = Color32::from_rgba_premultiplied(60, 20, 80, 80);
/// The path the robot drove in this run.
const TRAIL_COLOUR: Color32 = colour(Mark::Trail);
/// Trail points kept, and how far apart, mm.
const TRAIL_KEPT: usize = 20_000;
const TRAIL_STEP_MM: f64 = 2.0;
/// How often an idle window repaints (the ages it shows move, and a still
/// camera's noise), and one in use.
const IDLE_REPAINT: Duration = Duration::from_secs(1);
const BUSY_REPAINT: Duration = Duration::from_millis(30);

/// Who the window connects to, and as whom.
#[derive(Debug, Clone)]
struct Destination {
    url: String,
    role: Role,
    login: Login,
}

/// The Guest's window.
pub struct GuestApp {
    address: Destination,
    session: Session,
    connection: Connection,
    texture: Option<(u64, TextureHandle)>,
    /// Virtual joystick deflection: x = turn right, y = forward, each in −1..1.
    joystick: Vec2,
    goal: Goal,
    /// The points clicked to visit in order, for an experiment that
    /// defines waypoints.
    waypoints: Vec<Point>,
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
    /// What is typed in the login form: an account's name and password.
    typed_login: (String, String),
    /// Where the forecast's preview is.
    preview: preview::Preview,
    /// The recorded run played back instead of a Host's live one.
    replay: Option<vl_client::Replay>,
    /// Where saved definitions are kept (none: nowhere), the name typed
    /// for the next, and what the last save or load did.
    tasks: Option<vl_client::Tasks>,
    task_name: String,
    task_note: Option<String>,
    /// Where downloaded runs go (none: no downloads), the one coming, and
    /// what the last download or replay did.
    downloads: Option<PathBuf>,
    download: Option<vl_client::Downloading>,
    recordings_note: Option<String>,
    /// The user's controller's file, as typed or dropped, and what
    /// sending it did.
    controller_path: String,
    controller_note: Option<controller::ControllerNote>,
    /// The controller's file picker, while it is open.
    controller_picker: Option<egui_file::FileDialog>,
}

impl GuestApp {
    /// A window on the Host at `url`, connecting as `role` straight away
    /// (on the current tokio runtime). Only an address that cannot be a
    /// Host's is refused; an unreachable Host is shown in the window.
    pub fn new(url: &str, role: Role, login: Login) -> Result<Self, ClientError> {
        let address = Destination {
            url: url.to_owned(),
            role,
            login,
        };
        let connection = GuestApp::connect(&address)?;
        Ok(GuestApp::on(address, connection))
    }

    /// The window on `connection`, at `address`.
    fn on(address: Destination, connection: Connection) -> Self {
        GuestApp {
            address,
            session: Session::default(),
            connection,
            texture: None,
            joystick: Vec2::ZERO,
            goal: Goal::at(Point::default()),
            waypoints: Vec::new(),
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
            typed_login: Default::default(),
            preview: Default::default(),
            welcomes: 0,
            replay: None,
            tasks: None,
            task_name: String::new(),
            task_note: None,
            downloads: None,
            download: None,
            recordings_note: None,
            controller_path: String::new(),
            controller_note: None,
            controller_picker: None,
        }
    }

    /// The window downloading runs into `dir`.
    pub fn with_downloads(mut self, dir: PathBuf) -> Self {
        self.downloads = Some(dir);
        self
    }

    /// Plays `replay` in place of the live view; `Back to the lab` ends it.
    fn play(&mut self, replay: vl_client::Replay) {
        self.connection = Connection::detached();
        self.session = Session::default();
        self.forget_the_host();
        self.replay = Some(replay);
    }

    /// The window keeping its tasks in `tasks`.
    pub fn with_tasks(mut self, tasks: vl_client::Tasks) -> Self {
        self.tasks = Some(tasks);
        self
    }

    /// A window playing `replay` back, connected to no Host.
    pub fn replaying(replay: vl_client::Replay) -> Self {
        let address = Destination {
            url: replay.file.clone(),
            role: Role::Observer,
            login: Login::default(),
        };
        let mut app = GuestApp::on(address, Connection::detached());
        app.play(replay);
        app
    }

    /// The replay, when the window plays one back.
    pub fn replay(&mut self) -> Option<&mut vl_client::Replay> {
        self.replay.as_mut()
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
    fn connect(address: &Destination) -> Result<Connection, ClientError> {
        let connection = open(&address.url)?;
        connection.send(address.login.hello(address.role));
        Ok(connection)
    }

    /// Starts over on a new connection: what the old one knew is gone.
    fn reconnect(&mut self) {
        self.session = Session::default();
        self.forget_the_host();
        match GuestApp::connect(&self.address) {
            Ok(connection) => self.connection = connection,
            Err(e) => self.session.link = LinkState::Closed(e.to_string()),
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
        self.take_dropped(&ctx);
        self.show_controller_picker(&ctx);
        self.drive(&ctx);
        if let Some(replay) = &mut self.replay {
            // A replay chosen in a lab's window goes back to the lab after.
            let from_lab = self.address.url.starts_with("ws");
            let mut back = false;
            egui::Panel::top("replay").show(ui, |ui| {
                replay::controls(replay, ui);
                back = from_lab && ui.button("Back to the lab").clicked();
            });
            if back {
                self.replay = None;
                self.reconnect();
            }
        }
        egui::Panel::top("status").show(ui, |ui| self.status_bar(ui));
        // A width of its own, set by the window's: what opens in it (a
        // forecast's table) wraps instead of widening it, so the camera view
        // does not jump.
        let controls = (ui.available_width() * 0.3).clamp(250.0, 340.0);
        egui::Panel::left("controls")
            .exact_size(controls)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        if self.session.is_operator() && self.takes_commands() {
            egui::Panel::bottom("joystick").show(ui, |ui| self.joystick(ui));
        } else if self.session.is_operator() {
            egui::Panel::bottom("no stick").show(ui, |ui| {
                ui.label(match self.runs_a_controller() {
                    true => "Your controller drives this experiment's run, not the stick. STOP (Space) stops it.",
                    false => "This experiment holds the robot still: nothing to drive. STOP (Space) is for everyone.",
                });
            });
        } else if self.session.role.is_some() && self.replay.is_none() {
            egui::Panel::bottom("watching").show(ui, |ui| {
                ui.label(
                    "You are watching: only the operator drives. STOP (Space) is for everyone.",
                );
            });
        }
        if self.session.lab.is_some() || self.session.frame.is_some() {
            egui::Panel::bottom("view legend").show(ui, |ui| self.view_legend(ui));
        }
        if let Some(replay) = &self.replay {
            replay::results_panel(replay, ui);
        }
        egui::CentralPanel::default().show(ui, |ui| self.camera_view(ui));
        // Repaint when something moves; an idle window only keeps its
        // ages current (input repaints at once by itself).
        let moving = self
            .session
            .robot
            .as_ref()
            .is_some_and(|r| r.wheels.left_mm_s.abs().max(r.wheels.right_mm_s.abs()) > 0.5);
        let busy = self.replay.as_ref().is_some_and(|r| r.playing)
            || self.session.running
            || !self.session.ready()
            || moving
            || self.asked != Joystick::default();
        ctx.request_repaint_after(if busy { BUSY_REPAINT } else { IDLE_REPAINT });
    }

    /// Takes in everything that arrived since the last frame.
    fn pump(&mut self) {
        let mounts = self.session.mounts;
        let was_running = self.session.running;
        if let Some(replay) = &mut self.replay {
            replay.advance(&mut self.session);
        }
        while let Some(incoming) = self.connection.try_recv() {
            match incoming {
                Incoming::Part(header, bytes) => self.take_part(&header, &bytes),
                Incoming::Message(message) if self.still_writing(&message) => {}
                incoming => self.session.apply(incoming),
            }
        }
        self.retry_download();
        self.session.decode_frame();
        if self.session.welcomes != self.welcomes {
            // A new connection, perhaps to a Host started again.
            self.welcomes = self.session.welcomes;
            self.forget_the_host();
        }
        if let Some(lab) = &self.session.lab
            && self.session.mounts != mounts
        {
            // A mount (for a new operator too): nothing of the last one's stays on screen.
            self.plan_note = None;
            self.trail.clear();
            self.dragging_sample = None;
            self.waypoints.clear();
            if let Some(goal) = lab.scene.arena.goal {
                self.goal.x_mm = goal.x_mm;
                self.goal.y_mm = goal.y_mm;
            }
        }
        if self.session.running && !was_running && self.session.done.is_none() {
            self.trail.clear();
        }
        if let Some(replay) = &self.replay {
            // Scrubbed anywhere, the trail is where the robot went until then.
            self.trail = replay.trail(TRAIL_STEP_MM);
        } else if let Some(robot) = self.session.robot.as_ref().filter(|_| self.session.running) {
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
        // Nothing but the emergency stop drives a run that takes no
        // command: the user's controller's, or one holding the robot.
        if !self.session.is_operator() || !self.takes_commands() {
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
        let drive = Drive::from(self.teleop.wheels(&lab.scene.robot, asked));
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
        let turn = (w.right_mm_s - w.left_mm_s) / lab.scene.robot.wheel_base_mm;
        let Vector { x, y } = self.teleop.velocity_for(&lab.scene.robot, v, turn);
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
                .add_enabled(s.link == LinkState::Open && self.replay.is_none(), button)
                .on_hover_text("Emergency stop: the robot stops and the run ends (Space or Esc)")
                .clicked();
            if matches!(s.link, LinkState::Closed(_)) {
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
        let refused = s.errors.back().filter(|(code, _)| {
            matches!(code, ErrorCode::Unauthorized | ErrorCode::TooManyAttempts)
        });
        match &s.link {
            LinkState::Connecting if s.role.is_none() && refused.is_some() => add(
                "connected, not let in: log in with an account, or watch",
                Color32::YELLOW,
            ),
            LinkState::Connecting => add(
                &format!("connecting to {}…", self.address.url),
                Color32::YELLOW,
            ),
            LinkState::Unreachable { attempt, reason } => add(
                &format!("{reason} — trying again (attempt {attempt})"),
                Color32::YELLOW,
            ),
            LinkState::Open if self.replay.is_some() => add("a recorded run", Color32::LIGHT_BLUE),
            LinkState::Open => add("connected", Color32::GREEN),
            LinkState::Reconnecting { attempt, reason } => add(
                &format!("link lost ({reason}): reconnecting, attempt {attempt}…"),
                Color32::YELLOW,
            ),
            LinkState::Closed(why) => add(&format!("not connected: {why}"), Color32::RED),
        }
        if let (Some(role), Some(id), None) = (s.role, s.session_id, &self.replay) {
            add(&format!("{role}, session {id}"), Color32::GRAY);
        }
        if let (Some(Role::Operator), Some(ends)) = (s.role, s.slot_ends) {
            let left = ends.saturating_duration_since(std::time::Instant::now());
            add(
                &format!("your slot: {} left", panels::clock(left.as_secs())),
                Color32::LIGHT_BLUE,
            );
        }
        if s.role == Some(Role::Operator) && s.waiting > 0 {
            // Short: the status bar is one line at 800 px.
            add(&format!("{} waiting", s.waiting), Color32::LIGHT_BLUE);
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
}

/// The accessible name of the camera view, by which tests find it.
pub const CAMERA_VIEW: &str = "camera view";

/// What a C-space overlay was computed from.
#[derive(Debug, Clone, PartialEq)]
struct CSpaceKey {
    arena: vl_core::Arena,
    virtual_obstacles: Vec<Shape>,
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
    login: Login,
    pad: Option<Box<dyn Pad>>,
) -> Result<(), WindowError> {
    let mut app = GuestApp::new(url, role, login)?;
    if let Some(file) = Settings::default_path() {
        app = app.with_settings_file(file);
    }
    if let Some(pad) = pad {
        app = app.with_pad(pad);
    }
    if let Ok(tasks) = vl_client::Tasks::of_user() {
        app = app.with_tasks(tasks);
    }
    if let Some(dir) = vl_client::downloads_dir() {
        app = app.with_downloads(dir);
    }
    show_window(app)
}

/// Opens the Guest window playing the recorded run `replay` back.
pub fn run_replay_window(replay: vl_client::Replay) -> Result<(), WindowError> {
    show_window(GuestApp::replaying(replay))
}

fn show_window(app: GuestApp) -> Result<(), WindowError> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("vl guest")
            .with_inner_size([1100.0, 720.0]),
        ..Default::default()
    };
    let shown = eframe::run_native("vl guest", options, Box::new(move |_cc| Ok(Box::new(app))))
        .map_err(|e| WindowError::Window(e.to_string()));
    // The window is gone and with it its connection: give the goodbye
    // time to leave, so an operator's role is free at once.
    std::thread::sleep(GOODBYE_WAIT);
    shown
}

/// Whether a window can open here: a display is set.
pub fn display_available() -> bool {
    std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some()
}

/// Why the window did not run.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    #[error(transparent)]
    Destination(#[from] ClientError),
    #[error("the Guest window failed: {0}")]
    Window(String),
}

impl WindowError {
    /// Whether the Host's address itself is wrong: the user's to fix.
    pub fn is_bad_address(&self) -> bool {
        matches!(self, WindowError::Destination(c) if c.is_bad_address())
    }
}
