//! What the operator does: mount, define, start, stop and command; and the
//! emergency stop anyone may press.

use std::time::Instant;

use tracing::warn;
use vl_core::{
    Action, Definition, DeviceState, Drive, EndReason, ErrorCode, Experiment, GuestMessage,
    HostMessage, PLAN_MARGIN_MM, Point, Readiness, Shape, Stopper, plan_route_through,
};

use super::Hub;
use super::fields::field_job;
use crate::accounts::audit::AuditEntry;
use crate::lab::{Conduct, LabRequest};

/// The least time between two plans for the operator.
const PLAN_EVERY: std::time::Duration = std::time::Duration::from_millis(250);
/// The points definitions may carry a second, on average, and at once:
/// each is checked, sent to every watcher, recorded and tried on the
/// twin, so a flood of the longest would cost everyone; two of the longest
/// go at once, then one every five seconds.
pub(super) const DEFINITION_POINTS_PER_S: f64 = 2_000.0;
pub(super) const DEFINITION_POINTS_BURST: f64 = 20_000.0;

impl Hub {
    pub(super) fn operate(&mut self, id: u64, message: GuestMessage) {
        match message {
            GuestMessage::Mount { experiment } => self.mount(id, experiment),
            GuestMessage::Define { definition } => self.define(id, definition),
            GuestMessage::Controller {
                offset,
                total,
                data,
            } => self.take_controller_part(id, offset, total, &data),
            GuestMessage::Plan { goal, through } => self.plan(id, goal, &through),
            GuestMessage::Reset => self.ask_reset(id),
            GuestMessage::Start => self.start(id),
            GuestMessage::Stop => self.stop(id),
            GuestMessage::Command { event, seen, drive } => self.command(id, event, seen, drive),
            // Recordings are the connection's to answer.
            GuestMessage::Kick { .. }
            | GuestMessage::Recordings
            | GuestMessage::Download { .. } => {}
            GuestMessage::Queue | GuestMessage::LeaveQueue => {
                self.refuse(id, ErrorCode::NotAllowedNow, "you have control already");
            }
            GuestMessage::Hello { .. }
            | GuestMessage::EmergencyStop
            | GuestMessage::RequestFrame
            | GuestMessage::Ping { .. }
            | GuestMessage::Pong { .. }
            | GuestMessage::Bye => {}
        }
    }

    /// Mounts the experiment named `experiment`, if the lab offers it.
    fn mount(&mut self, id: u64, experiment: String) {
        let experiment = match self.config.experiments.get(&experiment) {
            Ok(offered) => offered.experiment().clone(),
            Err(unknown) => {
                let why = format!(
                    "this Host has no experiment \"{}\"; it offers {}",
                    unknown.name,
                    unknown.known.join(", ")
                );
                return self.refuse(id, ErrorCode::UnknownExperiment, why);
            }
        };
        if let Err(e) = self.put_up(experiment) {
            self.refuse(id, ErrorCode::NotAllowedNow, e.to_string());
        }
    }

    /// Mounts again, for a new operator, what the last one left mounted.
    pub(super) fn mount_kept(&mut self) {
        if let Some(experiment) = self.kept.take()
            && self.experiment.is_none()
            && let Err(e) = self.put_up(experiment)
        {
            warn!("the experiment left mounted could not be mounted again: {e}");
        }
    }

    /// Mounts `experiment` afresh: no definition yet, every client told.
    fn put_up(&mut self, experiment: Experiment) -> Result<(), vl_core::NotAllowed> {
        self.supervisor.mount(&experiment.id)?;
        self.kept = None;
        self.experiment = Some(experiment);
        self.definition = None;
        self.forecasts.forget();
        self.verdict = None;
        if let Some(mounted) = self.mounted() {
            self.broadcast(&mounted);
        }
        self.build_cspace();
        Ok(())
    }

    /// Takes the definition of the next run, once checked against the lab.
    fn define(&mut self, id: u64, definition: Definition) {
        if !self.permitted(id, Action::Define) {
            return;
        }
        if let Err(why) = definition.validate(&self.lab.info.arena, &self.lab.info.robot) {
            return self.refuse(id, ErrorCode::InvalidDefinition, why.to_string());
        }
        let definition = match self.experiment.as_ref().map(|e| e.limited(definition)) {
            Some(Ok(definition)) => definition,
            Some(Err(why)) => {
                return self.refuse(id, ErrorCode::InvalidDefinition, why.to_string());
            }
            None => return,
        };
        let size = definition.size() as f64;
        let wait = self.definitions.take(size);
        if !wait.is_zero() {
            self.definitions.refund(size);
            let why = format!(
                "definitions may carry {DEFINITION_POINTS_PER_S} points a second on average, and this one has {size}: define it again in {:.1} s",
                wait.as_secs_f64()
            );
            return self.refuse(id, ErrorCode::NotAllowedNow, why);
        }
        if self.experiment.as_ref().is_some_and(Experiment::follows)
            && let Some(cspace) = &self.cspace
            && let Some(i) = definition
                .path
                .iter()
                .position(|&p| !cspace.is_free(p, 0.0))
        {
            return self.refuse(
                id,
                ErrorCode::InvalidDefinition,
                format!(
                    "path point {i} is inside the C-space's obstacles: the robot's body would touch an obstacle there"
                ),
            );
        }
        if let Err(why) = self.named_controller(&definition) {
            return self.refuse(id, ErrorCode::InvalidDefinition, why);
        }
        self.supervise(id, Action::Define);
        self.definition = Some(definition.clone());
        self.broadcast(&HostMessage::Defined {
            definition: definition.clone(),
        });
        // The path was checked against the C-space above; the twin tries it.
        let (plans, forecasts) = self
            .experiment
            .as_ref()
            .map_or((false, false), |e| (e.plans(), e.forecasts()));
        if plans {
            self.happened(Action::PathPlanned);
        }
        if forecasts {
            self.ask_forecast(&definition);
        }
        self.build_field(&definition.virtual_obstacles);
    }

    /// Plans a path to `goal` from where the robot stands (through
    /// `through` first), for the operator to define: when a definition may
    /// be made, at most one plan every [`PLAN_EVERY`].
    fn plan(&mut self, id: u64, goal: Point, through: &[Point]) {
        if !self.experiment.as_ref().is_some_and(Experiment::plans) {
            let why =
                "paths are planned only in an experiment whose run plans one: mount one first";
            return self.refuse(id, ErrorCode::NotAllowedNow, why);
        }
        if !self.permitted(id, Action::Define) {
            return;
        }
        if let Some(last) = self.last_plan
            && last.elapsed() < PLAN_EVERY
        {
            let why = format!(
                "one plan every {} ms: ask again in a moment",
                PLAN_EVERY.as_millis()
            );
            return self.refuse(id, ErrorCode::NotAllowedNow, why);
        }
        let arena = &self.lab.info.arena;
        let inside = |v: f64, high: f64| v.is_finite() && (0.0..=high).contains(&v);
        let bounds = self
            .experiment
            .as_ref()
            .and_then(Experiment::waypoint_bounds);
        let most = bounds.map_or(0, |(_, max)| max.saturating_sub(1));
        if through.len() > most {
            let why = format!("a plan here goes through at most {most} points before its goal");
            return self.refuse(id, ErrorCode::InvalidDefinition, why);
        }
        if let Some(p) = through
            .iter()
            .chain([&goal])
            .find(|p| !inside(p.x_mm, arena.width_mm) || !inside(p.y_mm, arena.height_mm))
        {
            let why = format!(
                "the point ({}, {}) mm is outside the arena, {} by {} mm",
                p.x_mm, p.y_mm, arena.width_mm, arena.height_mm
            );
            return self.refuse(id, ErrorCode::InvalidDefinition, why);
        }
        self.last_plan = Some(Instant::now());
        let start = self.next_start();
        let arena = &self.lab.info.arena;
        let points: Vec<Point> = through.iter().copied().chain([goal]).collect();
        let robot = &self.lab.info.robot;
        match plan_route_through(arena, &[], robot, start, &points, PLAN_MARGIN_MM) {
            Ok(plan) => {
                let path = plan.points();
                self.send(id, HostMessage::Planned { goal, path });
            }
            Err(e) => self.refuse(id, ErrorCode::InvalidDefinition, format!("no path: {e}")),
        }
    }

    /// Drives the robot back to its start pose, unless a run is under way.
    fn ask_reset(&mut self, id: u64) {
        if self.supervisor.allows(Action::Stop) {
            return self.refuse(
                id,
                ErrorCode::NotAllowedNow,
                "a run is under way: stop it before the robot drives back to its start pose",
            );
        }
        self.reset();
    }

    /// Starts a run of the mounted experiment, when the lab is ready.
    fn start(&mut self, id: u64) {
        if self.readiness == Readiness::GettingReady {
            return self.refuse(
                id,
                ErrorCode::NotAllowedNow,
                "the lab is getting ready: the robot is driving back to its start pose; start when it is there",
            );
        }
        if self.lab.status.borrow().robot != DeviceState::Online {
            return self.refuse(
                id,
                ErrorCode::RobotOffline,
                "the robot does not answer: a run can start when it is back",
            );
        }
        // What runs: the definition in force (the defaults if none),
        // within the experiment's numbers.
        let defined = self.definition.clone().unwrap_or_default();
        let definition = match self.experiment.as_ref().map(|e| e.limited(defined)) {
            Some(Err(why)) => {
                return self.refuse(id, ErrorCode::InvalidDefinition, why.to_string());
            }
            Some(Ok(definition)) => definition,
            None => Definition::default(),
        };
        let controller = match self.named_controller(&definition) {
            Ok(taken) => taken,
            Err(why) => return self.refuse(id, ErrorCode::InvalidDefinition, why),
        };
        if self.supervise(id, Action::Start)
            && let Some(experiment) = self.experiment.clone()
        {
            self.last_event = 0;
            self.max_event_gap = 0;
            self.sync_violations = 0;
            self.last_command = Instant::now();
            self.runs += 1;
            self.run = Some(self.runs);
            self.driver = self
                .clients
                .get(&id)
                .map(|c| super::super::events::RunDriver {
                    connection: id,
                    admitted: c.admitted.clone(),
                });
            let user = self.user_of(id);
            self.run_log
                .started(self.runs, experiment.id.clone(), user.clone());
            self.config.audit.record(
                AuditEntry::new("run_started")
                    .connection(id)
                    .user(user.as_deref())
                    .detail(format!("run {}: {}", self.runs, experiment.id)),
            );
            let file = controller.as_ref().map(|t| t.file.clone());
            self.begin_recording(id, experiment.id.clone(), &definition, file);
            self.lab.request(LabRequest::Start {
                run: self.runs,
                definition: Box::new(definition),
                conduct: Conduct::from(&experiment),
                field: self.field.clone(),
                face: None,
                controller: controller.map(|t| t.module),
            });
            self.broadcast(&HostMessage::Started { event: 0 });
        }
    }

    /// Ends the run under way; the lab answers with its summary.
    /// Ends the operator's run. No net may keep a run going: the net's
    /// `stop` fires where it has one, and where it has none the run ends
    /// all the same; only a run that is not there, or already ending, is
    /// refused (saying why, as the net does).
    fn stop(&mut self, id: u64) {
        match self.supervisor.fire(Action::Stop) {
            Ok(()) => {}
            Err(e) if self.run.is_none() || self.stop_asked => {
                return self.refuse(id, ErrorCode::NotAllowedNow, e.to_string());
            }
            Err(e) => warn!(
                "the lab's net would not stop run {:?} ({e}): it stops regardless",
                self.run
            ),
        }
        self.stop_asked = true;
        // The lab answers with the run's summary; `done` follows.
        self.lab.request(LabRequest::Finish(EndReason::Stopped));
    }

    /// Passes a command on to the run, unless it is stale or not finite.
    fn command(&mut self, id: u64, event: u64, seen: Option<u64>, drive: Drive) {
        if !self.permitted(id, Action::Command) {
            return;
        }
        if let Some(experiment) = self.experiment.as_ref().filter(|e| !e.takes_commands()) {
            let why = if experiment.holds() {
                "this experiment's run holds the robot still: no command drives it"
            } else {
                "your controller drives this experiment's run: no command does"
            };
            return self.refuse(id, ErrorCode::NotAllowedNow, why);
        }
        if event <= self.last_event {
            return self.refuse(
                id,
                ErrorCode::StaleCommand,
                format!(
                    "command {event} is stale: {} was already executed",
                    self.last_event
                ),
            );
        }
        if !drive.is_finite() {
            return self.refuse(
                id,
                ErrorCode::BadMessage,
                "command speeds must be finite numbers",
            );
        }
        self.supervise(id, Action::Command);
        if let Some(seen) = seen {
            let gap = event.saturating_sub(seen);
            self.max_event_gap = self.max_event_gap.max(gap);
            self.sync_violations += u64::from(gap > 1);
        }
        self.last_event = event;
        self.last_command = Instant::now();
        self.record_command(GuestMessage::Command { event, seen, drive });
        self.lab.request(LabRequest::Drive { event, drive });
    }

    /// The mounted map's C-space (made when the Host started), then for
    /// teleoperation the map's potential field over it.
    fn build_cspace(&mut self) {
        self.cspace = self.map.cspace.clone();
        self.happened(Action::CspaceBuilt);
        self.build_field(&[]);
    }

    /// For teleoperation, the map's potential field over the C-space with
    /// `virtual_obstacles` grown in too: at once without them, else made
    /// off the hub (`field_built` fires when it is ready; the lab's net
    /// keeps the operator from driving until then).
    fn build_field(&mut self, virtual_obstacles: &[Shape]) {
        if !self
            .experiment
            .as_ref()
            .is_some_and(Experiment::assists_the_operator)
        {
            return;
        }
        if virtual_obstacles.is_empty() {
            self.fields.forget();
            self.field = self.map.field.clone();
            self.happened(Action::FieldBuilt);
        } else {
            self.fields
                .ask(field_job(&self.lab, virtual_obstacles.to_vec()));
        }
    }

    /// Stops the running robot at once and ends the run; the next run needs
    /// the operator's Start. It obeys no net: a run under way ends.
    pub(super) fn emergency_stop(&mut self, id: u64) {
        warn!(connection = id, "emergency stop");
        if self.run.is_some() {
            self.stop_asked = true;
            self.stopper = self
                .clients
                .get(&id)
                .and_then(|c| c.role)
                .map(|role| Stopper { role, session: id });
            self.lab
                .request(LabRequest::Finish(EndReason::EmergencyStop));
        }
        // The drive back to the start pose stops too; the lab is ready
        // where the robot stands, and the operator may ask again.
        if self.readiness == Readiness::GettingReady {
            if self.reset_run.is_some() {
                self.lab
                    .request(LabRequest::Finish(EndReason::EmergencyStop));
            } else {
                self.set_readiness(Readiness::Ready);
            }
        }
    }
}
