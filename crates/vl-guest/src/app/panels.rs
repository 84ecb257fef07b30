//! The side panel's controls: mount, define (the goal, the path, virtual
//! obstacles, the settings) and execute, and the on-screen joystick.

use egui::{Color32, Sense, Stroke, Vec2};
use vl_core::{
    Action, DefineKind, Definition, EndReason, ErrorCode, Experiment, GuestMessage, LOOKAHEAD_MM,
    Role,
};

use super::{FORCE_COLOUR, GuestApp, JOYSTICK_PX, ROBOT_COLOUR};
use crate::netview;
use vl_client::Login;
use vl_client::Route;
use vl_client::{MARGIN_MM, MAX_SPEED_MM_S};

impl GuestApp {
    pub(super) fn controls(&mut self, ui: &mut egui::Ui) {
        // A recording played back has no Host to log in to or ask.
        if self.replay.is_none() {
            self.account_panel(ui);
        }
        if self.session.role == Some(Role::Observer) && self.replay.is_none() {
            self.line_panel(ui);
        }
        if let (Some(step), None) = (self.session.next_step(), &self.replay) {
            ui.label(egui::RichText::new(step).strong());
            ui.separator();
        }
        if self.replay.is_none() {
            self.recordings_panel(ui);
        }
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
        if let Some(experiment) = self.session.mounted().cloned() {
            ui.separator();
            if self.session.is_operator() {
                self.define_panel(ui, &experiment);
                self.tasks_panel(ui, &experiment.id);
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
            self.forecast_panel(ui);
            if !self.session.ready() {
                ui.colored_label(
                    Color32::YELLOW,
                    "Getting ready: the robot drives back to its start pose.",
                );
            }
            if let Some(done) = &self.session.done {
                let goal = match done.reached_goal {
                    true if done.reason == EndReason::GoalReached => "",
                    true => ", goal reached",
                    false if experiment.ends_at_goal() => ", goal not reached",
                    false => "",
                };
                let visited = done.waypoints.map_or(String::new(), |w| {
                    format!(", {} of {} points visited", w.visited, w.of)
                });
                ui.label(format!(
                    "Last run: {}{goal}{visited} after {:.1} s, {:.0} mm driven, {} contacts.",
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
                .show(ui, |ui| netview::show(ui, &self.session));
        }
        self.robot_panel(ui);
        // A refused forecast is shown with the forecast, where it fails.
        let errors: Vec<&str> = (self.session.errors.iter().rev())
            .filter(|(code, _)| *code != ErrorCode::ForecastRefused)
            .map(|(_, message)| message.as_str())
            .collect();
        if !errors.is_empty() {
            ui.separator();
            ui.heading("Host said");
            for message in errors {
                ui.colored_label(Color32::LIGHT_RED, message);
            }
        }
    }

    /// The robot as last reported: pose, wheels, proximity sensors.
    fn robot_panel(&self, ui: &mut egui::Ui) {
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
    }

    /// Who the window is: the account it logged in as (and a way out), or a
    /// form to log in with one, to drive or to watch.
    fn account_panel(&mut self, ui: &mut egui::Ui) {
        if let Some(user) = self.session.user.clone() {
            ui.horizontal(|ui| {
                ui.label(format!("Logged in as {user}"));
                if ui.button("Log out").clicked() {
                    self.log_in(Login::default(), Role::Observer);
                }
            });
            ui.separator();
            return;
        }
        let refused = self
            .session
            .errors
            .iter()
            .any(|(code, _)| *code == ErrorCode::Unauthorized);
        egui::CollapsingHeader::new("Log in")
            .default_open(refused || self.session.role.is_none())
            .show(ui, |ui| {
                let (user, password) = &mut self.typed_login;
                ui.add(egui::TextEdit::singleline(user).hint_text("account"));
                ui.add(
                    egui::TextEdit::singleline(password)
                        .password(true)
                        .hint_text("password"),
                );
                let typed = !user.is_empty() && !password.is_empty();
                ui.horizontal(|ui| {
                    for (label, role) in [
                        ("Log in to drive", Role::Operator),
                        ("to watch", Role::Observer),
                    ] {
                        if ui.add_enabled(typed, egui::Button::new(label)).clicked() {
                            let (user, password) = std::mem::take(&mut self.typed_login);
                            self.log_in(Login::user(user, password), role);
                        }
                    }
                });
            });
        ui.separator();
    }

    /// An observer's way to control: a place in line, and where it stands.
    fn line_panel(&mut self, ui: &mut egui::Ui) {
        match self.session.queue {
            Some(place) => {
                let wait = place.by.map_or(
                    ": slots have no length here, so you drive when the operator leaves".to_owned(),
                    |by| {
                        let s = by.saturating_duration_since(std::time::Instant::now());
                        format!(", control within {}", clock(s.as_secs()))
                    },
                );
                ui.label(format!(
                    "You are {} in line for control ({} waiting){wait}.",
                    ordinal(place.position),
                    place.length
                ));
                if ui.button("Leave the line").clicked() {
                    self.connection.send(GuestMessage::LeaveQueue);
                }
            }
            None => {
                if let Some(ended) = self.session.control_ended {
                    let why = match ended {
                        vl_core::EndReason::SlotEnded => "your slot ended".to_owned(),
                        vl_core::EndReason::Kicked => "an administrator ended your turn".to_owned(),
                        other => other.to_string(),
                    };
                    ui.label(format!(
                        "You watch now: {why}, and the next in line drives. Ask for control to drive again."
                    ));
                }
                if ui
                    .button("Ask for control")
                    .on_hover_text("Join the line: you drive when your turn comes")
                    .clicked()
                {
                    self.connection.send(GuestMessage::Queue);
                }
            }
        }
        ui.separator();
    }

    /// Starts over on a new connection, saying hello as `login`.
    fn log_in(&mut self, login: Login, role: Role) {
        self.address.login = login;
        self.address.role = role;
        self.reconnect();
    }

    /// The operator's definition, as the experiment declares it: the goal
    /// (and the path planned to it, when the run follows one), virtual
    /// obstacles, the settings.
    fn define_panel(&mut self, ui: &mut egui::Ui, experiment: &Experiment) {
        ui.heading("Define");
        ui.label(&experiment.help);
        if experiment.runs_a_controller() {
            self.controller_row(ui);
        }
        if let Some((min, max)) = self.waypoint_bounds() {
            ui.horizontal(|ui| {
                ui.label(format!(
                    "{} of {min} to {max} waypoints",
                    self.waypoints.len()
                ));
                if ui
                    .add_enabled(
                        !self.waypoints.is_empty(),
                        egui::Button::new("Clear points"),
                    )
                    .clicked()
                {
                    self.waypoints.clear();
                }
            });
        } else {
            self.goal_fields(ui);
        }
        self.define_row(ui);
        if experiment.defines(DefineKind::Obstacles) {
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
        }
        if let Some(note) = &self.plan_note {
            ui.label(note);
        }
        self.settings_panel(ui);
    }

    /// The goal's position, typed (a click on the view sets it too).
    fn goal_fields(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.label("goal x");
            ui.add(egui::DragValue::new(&mut self.goal.x_mm).suffix(" mm"));
            ui.label("y");
            ui.add(egui::DragValue::new(&mut self.goal.y_mm).suffix(" mm"));
        });
    }

    /// How close counts as there, and Define.
    fn define_row(&mut self, ui: &mut egui::Ui) {
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
    }

    /// How many waypoints the mounted experiment visits, at least and at
    /// most; none when it defines none.
    pub(super) fn waypoint_bounds(&self) -> Option<(usize, usize)> {
        self.session.mounted()?.waypoint_bounds()
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
            let between_runs = !self.session.net_allows(Action::Stop) && self.session.ready();
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
    /// both. A run that follows needs the path; one driven by stick,
    /// without one, has the goal alone as a target to drive to by hand.
    fn define(&mut self) {
        if self.runs_a_controller() {
            if let Some(definition) = self.controller_definition() {
                self.connection.send(GuestMessage::Define { definition });
            }
            return;
        }
        let Some(lab) = &self.session.lab else { return };
        let start = self
            .session
            .robot
            .as_ref()
            .map_or(lab.scene.arena.start, |r| r.pose);
        let obstacles = self.virtual_obstacles.clone();
        let planned = match self.waypoint_bounds() {
            Some((min, _)) if self.waypoints.len() < min => {
                self.plan_note = Some(format!(
                    "Not defined: click at least {min} points to visit, in order."
                ));
                return;
            }
            Some(_) => Route::plan_through(
                lab,
                start,
                &self.waypoints,
                self.goal.tolerance_mm,
                obstacles.clone(),
                &self.settings,
            ),
            None => Route::plan(lab, start, self.goal, obstacles.clone(), &self.settings),
        };
        let definition = match planned {
            Ok(route) => {
                self.plan_note = Some(format!(
                    "path {:.0} mm; the body keeps {:.0} mm from obstacles",
                    route.plan.length_mm,
                    route.body_clearance_mm(lab)
                ));
                route.definition
            }
            Err(e) if self.session.mounted().is_some_and(Experiment::follows) => {
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

    pub(super) fn joystick(&mut self, ui: &mut egui::Ui) {
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
}

/// 1st, 2nd, 3rd, 4th…
fn ordinal(n: u32) -> String {
    let suffix = match (n % 10, n % 100) {
        (1, 11) | (2, 12) | (3, 13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

/// Seconds as minutes and seconds: 9:05.
pub(super) fn clock(seconds: u64) -> String {
    format!("{}:{:02}", seconds / 60, seconds % 60)
}
