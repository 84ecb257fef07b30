//! The hub: the one owner of session state. It decides who is operator,
//! runs the supervisor net that says which action may happen when, keeps
//! the definition, relays commands to the lab, and enforces the operator's
//! lease. It never waits on a client: each has a bounded outbox, and a
//! client that lets it fill is let go.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::Message;
use tracing::{debug, info, warn};
use vl_core::{
    AccessEvent, Action, CSpace, Definition, EndReason, ErrorCode, Experiment, GuestMessage,
    HostMessage, MapField, MountedLab, Readiness, Role, Stopper, Supervisor, Wire,
};

use super::HostConfig;
use crate::accounts::audit::AuditEntry;
use crate::accounts::gate::Admitted;
use crate::lab::{Finished, Lab};
use fields::Map;
pub(crate) use forecasts::ForecastJob;
pub use forecasts::{ForecastSettings, MOST_SEEDS as MOST_FORECAST_SEEDS};
use vl_record::Level;
use worker::JobThread;

mod access;
mod controllers;
mod ending;
mod fields;
mod forecasts;
mod operate;
mod queue;
mod recording;
mod reset;
mod status;
#[cfg(test)]
mod tests;
mod worker;

/// Messages waiting for one client, at most; feedback and frames are not
/// queued (each connection takes only the newest).
pub const OUTBOX: usize = 64;
/// How often the hub looks at the operator's lease.
const LEASE_CHECK: Duration = Duration::from_millis(250);

/// What a connection tells the hub.
pub enum ToHub {
    /// A new connection, with the path its WebSocket opened.
    Join(u64, mpsc::Sender<ToConnection>, Option<String>),
    /// A hello whose sender the gate identified.
    Hello {
        id: u64,
        admitted: Admitted,
        protocol: u32,
        role: Role,
        resume: Option<String>,
    },
    Message(u64, GuestMessage),
    /// The accounts file was read again, with these accounts.
    Accounts(Arc<crate::accounts::users::Users>),
    /// An administrator asks how the Host (or the gateway) is.
    Status(tokio::sync::oneshot::Sender<Status>),
    /// What a late observer is told on its welcome (for a gateway's
    /// watchers of this cell).
    CatchUp(tokio::sync::oneshot::Sender<Vec<HostMessage>>),
    /// The connection closed; true when the client meant to leave (said
    /// bye or closed the WebSocket), false when its link dropped.
    Leave(u64, bool),
}

/// What the hub tells a connection.
pub enum ToConnection {
    /// A message, encoded once for every client it goes to.
    Send(Message),
    /// The client was welcomed: start streaming feedback and frames.
    Subscribe,
    /// The client was welcomed: start streaming these feedback and frames
    /// (a gateway's Guest: its cell's).
    Watch(Box<Streams>),
    /// The lab ends this connection, saying why (an administrator's kick).
    End(vl_core::ErrorCode, String),
}

/// A cell's newest feedback and frame, as a gateway mirrors them.
pub struct Streams {
    pub feedback: tokio::sync::watch::Receiver<Option<HostMessage>>,
    pub frames: tokio::sync::watch::Receiver<Option<bytes::Bytes>>,
}

/// What `GET /status` shows: a Host's state, or a gateway's.
#[derive(serde::Serialize)]
#[serde(untagged)]
pub enum Status {
    Host(Box<vl_core::HostStatus>),
    Gateway(vl_core::GatewayStatus),
}

struct Client {
    out: mpsc::Sender<ToConnection>,
    role: Option<Role>,
    /// Who its hello proved it is.
    admitted: Admitted,
}

/// An operator whose link dropped: the role is theirs until `until`, for
/// a hello that carries `resume`.
struct Away {
    resume: String,
    until: Instant,
}

/// Whether a run that ended so is followed by the drive back to the start
/// pose. Not after an emergency stop (someone saw something wrong: nothing
/// moves until the operator starts again), a fault (the robot does not
/// answer), a robot the camera lost (it would drive blind) or one held
/// back (it is too unsure where it is to pass what lies between it and
/// the start).
fn resets_after(reason: EndReason) -> bool {
    !matches!(
        reason,
        EndReason::EmergencyStop | EndReason::Fault | EndReason::RobotLost | EndReason::HeldBack
    )
}

/// The way back to the start pose, or why there is none.
type ResetRoute = Result<Definition, String>;

/// The one owner of session state.
pub(crate) struct Hub {
    lab: Lab,
    config: Arc<HostConfig>,
    supervisor: Supervisor,
    clients: HashMap<u64, Client>,
    operator: Option<u64>,
    /// The account of the operator (or of one held for the grace).
    operator_user: Option<String>,
    /// The operator's secret for coming back after a dropped link.
    resume: Option<String>,
    /// An operator whose link dropped, while their grace lasts.
    away: Option<Away>,
    /// Who waits for control, first first.
    queue: std::collections::VecDeque<queue::Spot>,
    /// Whether the line changed since it was last told, and when that was.
    line_changed: bool,
    line_told: Option<Instant>,
    /// When the operator's slot ends, when slots have a length.
    slot_until: Option<Instant>,
    /// The mounted experiment.
    experiment: Option<Experiment>,
    /// What the last operator left mounted: mounted again for the next,
    /// who plans, defines and starts at once.
    kept: Option<Experiment>,
    definition: Option<Definition>,
    /// Event number of the last command accepted in this run.
    last_event: u64,
    /// The run's synchronisation so far: the largest `event − seen`, and
    /// how many commands ran more than one event ahead.
    max_event_gap: u64,
    sync_violations: u64,
    /// When the operator last started or commanded the run under way.
    last_command: Instant,
    /// When the operator last had a path planned (`plan`): plans are
    /// the Host's work, so they are spaced.
    last_plan: Option<Instant>,
    /// The points the operator's definitions may still carry now.
    definitions: super::bucket::Bucket,
    /// The number of the run under way (kept until the lab reports its end).
    run: Option<u64>,
    /// How many runs have started.
    runs: u64,
    /// The latest runs, for the administrator.
    run_log: status::RunLog,
    /// The devices' state last seen, to log faults and returns.
    devices: crate::lab::LabStatus,
    /// The mounted map grown by the robot's radius (the `cspace` chart's work).
    cspace: Option<Arc<CSpace>>,
    /// The map's potential field for teleoperation runs, over the C-space
    /// and the definition's virtual obstacles (the `field` chart's work).
    field: Option<Arc<MapField>>,
    /// The lab's map, its C-space and field without virtual obstacles: the
    /// same for every mount, so made once, when the Host starts.
    map: Map,
    /// Fields for definitions with virtual obstacles, made off the hub.
    fields: JobThread<Option<MapField>>,
    /// Forecasts of navigation definitions, made off the hub, and the
    /// verdict on the definition in force.
    forecasts: JobThread<forecasts::Forecasted>,
    verdict: Option<vl_core::ForecastVerdict>,
    /// Whether a run may start, and the run that drives the robot back
    /// to the start pose while it may not.
    readiness: Readiness,
    reset_run: Option<u64>,
    /// Routes back to the start pose, planned off the hub.
    reset_routes: (
        mpsc::UnboundedSender<ResetRoute>,
        mpsc::UnboundedReceiver<ResetRoute>,
    ),
    /// Who pressed the emergency stop that is ending the run.
    stopper: Option<Stopper>,
    /// A stop of the run under way was asked of the lab: it is ending.
    stop_asked: bool,
    /// The run being recorded.
    recording: Option<recording::RunRecording>,
    /// Every broadcast, for live views made of it (Foxglove's).
    live: super::events::LiveEvents,
    /// Who drives the run under way, told with its end.
    driver: Option<super::events::RunDriver>,
    /// Where the lab's events are told.
    events: super::events::LabEvents,
    /// The operator's own controller, checked, and one arriving in parts.
    controller: Option<controllers::Taken>,
    upload: Option<controllers::Upload>,
    /// The bytes of controllers that may still be checked now.
    checks: super::bucket::Bucket,
}

impl Hub {
    pub(crate) fn new(
        lab: Lab,
        config: Arc<HostConfig>,
        supervisor: Supervisor,
        events: super::events::LabEvents,
    ) -> Hub {
        let devices = *lab.status.borrow();
        Hub {
            map: Map::new(&lab),
            lab,
            config,
            supervisor,
            clients: HashMap::new(),
            operator: None,
            resume: None,
            away: None,
            queue: std::collections::VecDeque::new(),
            line_changed: false,
            line_told: None,
            slot_until: None,
            experiment: None,
            kept: None,
            definition: None,
            last_event: 0,
            max_event_gap: 0,
            sync_violations: 0,
            last_command: Instant::now(),
            last_plan: None,
            definitions: super::bucket::Bucket::new(
                operate::DEFINITION_POINTS_PER_S,
                operate::DEFINITION_POINTS_BURST,
            ),
            run: None,
            runs: 0,
            operator_user: None,
            run_log: status::RunLog::default(),
            live: super::events::LiveEvents::default(),
            devices,
            cspace: None,
            field: None,
            fields: JobThread::new("vl field"),
            forecasts: JobThread::new("vl forecast"),
            verdict: None,
            readiness: Readiness::Ready,
            reset_run: None,
            reset_routes: mpsc::unbounded_channel(),
            stopper: None,
            stop_asked: false,
            recording: None,
            driver: None,
            events,
            controller: None,
            upload: None,
            checks: super::bucket::Bucket::new(
                controllers::CHECKED_BYTES_PER_S,
                controllers::CHECKED_BYTES_BURST,
            ),
        }
    }

    pub(crate) async fn run(mut self, mut inbox: mpsc::Receiver<ToHub>) {
        let mut lease = tokio::time::interval(LEASE_CHECK);
        let mut status = self.lab.status.clone();
        self.begin_idle();
        loop {
            tokio::select! {
                // The lab sets a device's state before it ends the run that
                // state ended: polling status first keeps that order on the
                // wire, so a Guest reads the cause before the `done` it explains.
                // Clients come last: however busy they keep the Hub, a run's
                // end and a silent operator's lease are still seen.
                biased;
                Ok(()) = status.changed() => {
                    status.mark_unchanged();
                    self.devices_changed();
                    self.broadcast(&self.status());
                }
                Some(Finished(run, summary)) = self.lab.finished.recv() => {
                    if self.reset_run == Some(run) {
                        self.reset_done(&summary);
                        continue;
                    }
                    // Only the run under way may end: a previous operator's
                    // run that ends late must not end the next one's.
                    if self.run != Some(run) {
                        debug!(run, "a past run's end, after the next began");
                        continue;
                    }
                    self.run_ended(run, summary);
                }
                Some(route) = self.reset_routes.1.recv() => self.reset_planned(route),
                Some((number, forecasted)) = self.forecasts.done.recv() => {
                    self.forecast_done(number, forecasted);
                }
                Some((number, field)) = self.fields.done.recv() => {
                    if let Some(field) = self.fields.finished(number, field) {
                        self.field = field.map(Arc::new);
                        self.happened(Action::FieldBuilt);
                    }
                }
                _ = lease.tick() => {
                    self.check_lease();
                    self.check_slot();
                }
                message = inbox.recv() => match message {
                    Some(ToHub::Join(id, out, _)) => {
                        let admitted = Admitted::anyone();
                        self.clients.insert(id, Client { out, role: None, admitted });
                    }
                    Some(ToHub::Hello { id, admitted, protocol, role, resume }) => {
                        self.greet(id, admitted, protocol, role, resume);
                    }
                    Some(ToHub::Message(id, message)) => self.handle(id, message),
                    Some(ToHub::Status(answer)) => {
                        let _ = answer.send(Status::Host(Box::new(self.host_status())));
                    }
                    Some(ToHub::CatchUp(answer)) => {
                        let welcome = self.welcome(0, Role::Observer, None, None);
                        let _ = answer.send([welcome].into_iter().chain(self.catch_up()).collect());
                    }
                    Some(ToHub::Leave(id, meant)) => self.leave(id, meant),
                    Some(ToHub::Accounts(users)) => self.accounts_changed(&users),
                    None => return,
                },
            }
            self.tell_state();
            self.tell_line_if_due();
            // With the shipped design, the line and the net always agree;
            // a design of one's own may refuse what happens anyway (a
            // person leaving), which `seat` logs.
            debug_assert!(
                self.config.nets.is_some() || self.seats_apart().is_none(),
                "the line and the access net disagree: {:?}",
                self.seats_apart()
            );
        }
    }

    /// The run under way ended: its summary completed, told, logged (and
    /// graded for an LMS), its recording closed, the lab made ready again.
    fn run_ended(&mut self, run: u64, mut summary: vl_core::Summary) {
        self.run = None;
        self.stop_asked = false;
        self.run_log.ended(run, summary.reason);
        if self.supervisor.allows(Action::Finish) {
            self.happened(Action::Finish);
        }
        summary.experiment = self.experiment.as_ref().map(|e| e.id.to_string());
        summary.max_event_gap = self.max_event_gap;
        summary.sync_violations = self.sync_violations;
        summary.stopped_by = self
            .stopper
            .take()
            .filter(|_| summary.reason == EndReason::EmergencyStop);
        self.compare_with_forecast(&mut summary);
        self.note_recording(&mut summary);
        info!(run, reason = %summary.reason, reached_goal = summary.reached_goal, "run ended");
        let driver = self.driver.take();
        let user = driver.as_ref().and_then(|d| d.admitted.identity.name());
        self.config.audit.record(
            AuditEntry::new("run_ended")
                .user(user)
                .detail(format!("run {run}: {}", summary.ending())),
        );
        self.events.tell(super::events::LabEvent::RunEnded(Arc::new(
            super::events::RunEnded {
                run: Some(run),
                driver,
                summary: summary.clone(),
            },
        )));
        let reset = resets_after(summary.reason);
        self.broadcast(&HostMessage::Done {
            summary: Box::new(summary),
        });
        // The run's last firings go in its file before it closes.
        self.tell_state();
        self.end_recording();
        let readiness = self.readiness;
        if reset {
            self.reset();
        }
        // Who joins later hears how the lab was last used (a
        // drive back has said so with its own status).
        if self.readiness == readiness {
            self.broadcast(&self.status());
        }
        // The next run starts elsewhere: the definition is tried again.
        if let (Some(true), Some(definition)) = (
            self.experiment.as_ref().map(Experiment::forecasts),
            self.definition.clone(),
        ) {
            let definition = self.refit(definition);
            self.ask_forecast(&definition);
        }
    }

    /// Queues `message` for client `id`; a client whose outbox is full is
    /// let go (its connection says why and closes).
    fn send_encoded(&mut self, id: u64, message: Message) {
        let Some(client) = self.clients.get(&id) else {
            return;
        };
        if let Err(mpsc::error::TrySendError::Full(_)) =
            client.out.try_send(ToConnection::Send(message))
        {
            debug!(connection = id, "a client that does not read: let go");
            self.clients.remove(&id);
            self.leave(id, false);
        }
    }

    fn send(&mut self, id: u64, message: HostMessage) {
        self.send_encoded(id, Message::text(message.encode()));
    }

    fn refuse(&mut self, id: u64, code: ErrorCode, message: impl Into<String>) {
        let message = message.into();
        // The operator's refusals are part of the experiment; those of
        // others only of the lab's log (one line each would let anyone
        // write thousands into the run's record).
        if self.operator == Some(id) {
            self.record_log(Level::Warning, format!("refused ({code}): {message}"));
        } else {
            debug!(connection = id, %code, "refused: {message}");
        }
        self.send(id, HostMessage::error(code, message));
    }

    /// The account client `id` logged in with, if any.
    fn user_of(&self, id: u64) -> Option<String> {
        let client = self.clients.get(&id)?;
        client.admitted.identity.name().map(str::to_owned)
    }

    /// Tells every broadcast to `live` too.
    pub(crate) fn with_live(mut self, live: super::events::LiveEvents) -> Hub {
        self.live = live;
        self
    }

    /// Sends to every welcomed client, encoded once.
    fn broadcast(&mut self, message: &HostMessage) {
        self.record_sent(message);
        self.live
            .tell(|| super::events::LiveEvent::Told(Arc::new(message.clone())));
        let encoded = Message::text(message.encode());
        let welcomed: Vec<u64> = self
            .clients
            .iter()
            .filter(|(_, c)| c.role.is_some())
            .map(|(id, _)| *id)
            .collect();
        for id in welcomed {
            self.send_encoded(id, encoded.clone());
        }
    }

    /// Tells every client what the supervisor fired since it last told,
    /// and logs each firing.
    fn tell_state(&mut self) {
        let Some(state) = self.supervisor.take_state() else {
            return;
        };
        for fired in &state.fired {
            info!(lab = %fired.lab, transition = %fired.transition, "fired");
            let line = format!("{}: fired {}", fired.lab, fired.transition);
            self.record_log(Level::Info, line);
        }
        self.broadcast(&HostMessage::State(Box::new(state)));
    }

    /// Fires an action of the lab's own (a computation done, a run ended)
    /// that the net should enable; says so in the log if it does not.
    fn happened(&mut self, action: Action) {
        if let Err(e) = self.supervisor.fire(action) {
            warn!("the lab's net did not expect this: {e}");
        }
    }

    fn handle(&mut self, id: u64, message: GuestMessage) {
        let Some(role) = self.clients.get(&id).map(|c| c.role) else {
            return;
        };
        match (role, message) {
            // Hellos come through the gate, as `ToHub::Hello`.
            (_, GuestMessage::Hello { .. }) => {}
            (None, _) => self.refuse(id, ErrorCode::HelloFirst, "send hello first"),
            // Anyone watching may stop the robot: safety before roles.
            (Some(_), GuestMessage::EmergencyStop) => self.emergency_stop(id),
            // Anyone watching may want to see the scene.
            (Some(_), GuestMessage::RequestFrame) => self.lab.request_frame(),
            (Some(_), GuestMessage::Kick { session }) => self.kick(id, session),
            (Some(Role::Observer), GuestMessage::Queue) => self.join_queue(id),
            (Some(Role::Observer), GuestMessage::LeaveQueue) => {
                self.leave_queue(id, AccessEvent::LeaveQueue)
            }
            (Some(Role::Observer), other) => self.refuse(
                id,
                ErrorCode::NotOperator,
                format!("observers watch; only the operator may {}", other.kind()),
            ),
            (Some(Role::Operator), message) => self.operate(id, message),
        }
    }

    fn mounted(&self) -> Option<HostMessage> {
        self.experiment.as_ref().map(|experiment| {
            HostMessage::Mounted(Box::new(MountedLab {
                experiment: experiment.id.clone(),
                scene: self.scene(),
            }))
        })
    }

    /// The lab's floor, robot and camera: what a Guest draws it with.
    fn scene(&self) -> vl_core::LabScene {
        let info = &self.lab.info;
        vl_core::LabScene {
            arena: info.arena.clone(),
            robot: info.robot.clone(),
            camera: info.camera,
        }
    }

    /// Whether the supervisor enables `action` now; if not, tells the
    /// operator why.
    fn permitted(&mut self, id: u64, action: Action) -> bool {
        match self.supervisor.check(action) {
            Ok(()) => true,
            Err(e) => {
                self.refuse(id, ErrorCode::NotAllowedNow, e.to_string());
                false
            }
        }
    }

    /// Fires `action` in the supervisor, or tells the operator why not.
    fn supervise(&mut self, id: u64, action: Action) -> bool {
        self.permitted(id, action) && self.supervisor.fire(action).is_ok()
    }

    /// The status every client is told: the devices, and whether a run may start.
    fn status(&self) -> HostMessage {
        let last_run = self.run_log.last_ended();
        self.lab.status.borrow().message(self.readiness, last_run)
    }
}
