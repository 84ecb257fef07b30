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
    Action, CSpace, Definition, DeviceState, EndReason, ErrorCode, Experiment, Goal, GuestMessage,
    HostMessage, MapField, MountedLab, Named, PROTOCOL_VERSION, Pose, Readiness, Role, Shape,
    Stopper, Supervisor, Wire, disc_cspace, plan_route, wrap_angle,
};

use super::HostConfig;
use super::connection::error;
use crate::lab::{Finished, Lab, LabRequest, map_field};

/// Messages waiting for one client, at most; feedback and frames are not
/// queued (each connection takes only the newest).
pub(crate) const OUTBOX: usize = 64;
/// How often the hub looks at the operator's lease.
const LEASE_CHECK: Duration = Duration::from_millis(250);
/// A robot this near the start pose, mm and rad, is back: no drive needed
/// (and the drive back ends this near it).
const AT_START_MM: f64 = 5.0;
const AT_START_RAD: f64 = 0.15;
/// The drive back to the start pose gives up after this long, s.
const RESET_LIMIT_S: f64 = 90.0;

/// What a connection tells the hub.
pub(crate) enum ToHub {
    Join(u64, mpsc::Sender<ToConnection>),
    Message(u64, GuestMessage),
    /// The connection closed; true when the client meant to leave (said
    /// bye or closed the WebSocket), false when its link dropped.
    Leave(u64, bool),
}

/// What the hub tells a connection.
pub(crate) enum ToConnection {
    /// A message, encoded once for every client it goes to.
    Send(Message),
    /// The client was welcomed: start streaming feedback and frames.
    Subscribe,
}

struct Client {
    out: mpsc::Sender<ToConnection>,
    role: Option<Role>,
}

/// An operator whose link dropped: the role is theirs until `until`, for
/// a hello that carries `resume`.
struct Away {
    resume: String,
    until: Instant,
}

/// A secret no client can guess: SipHash keyed afresh from the operating
/// system's randomness by the standard library, over a counter and the
/// clock, twice over for 128 bits.
fn secret() -> String {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static DRAWN: AtomicU64 = AtomicU64::new(0);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    (0..2)
        .map(|_| {
            let mut h = std::collections::hash_map::RandomState::new().build_hasher();
            h.write_u64(DRAWN.fetch_add(1, Ordering::Relaxed));
            h.write_u128(now);
            format!("{:016x}", h.finish())
        })
        .collect()
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
    /// The operator's secret for coming back after a dropped link.
    resume: Option<String>,
    /// An operator whose link dropped, while their grace lasts.
    away: Option<Away>,
    /// The mounted experiment.
    experiment: Option<Experiment>,
    definition: Option<Definition>,
    /// Event number of the last command accepted in this run.
    last_event: u64,
    /// The run's synchronisation so far: the largest `event − seen`, and
    /// how many commands ran more than one event ahead.
    max_event_gap: u64,
    sync_violations: u64,
    /// When the operator last started or commanded the run under way.
    last_command: Instant,
    /// The number of the run under way (kept until the lab reports its end).
    run: Option<u64>,
    /// How many runs have started.
    runs: u64,
    /// The mounted map grown by the robot's radius (the `cspace` chart's work).
    cspace: Option<Arc<CSpace>>,
    /// The map's potential field for teleoperation runs, over the C-space
    /// and the definition's virtual obstacles (the `field` chart's work).
    field: Option<Arc<MapField>>,
    /// The lab's map, its C-space and field without virtual obstacles: the
    /// same for every mount, so made once, when the Host starts.
    map: Map,
    /// Fields for definitions with virtual obstacles, made off the hub.
    fields: FieldWorker,
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
}

/// What the lab's map always gives: its C-space and (for teleoperation)
/// its potential field.
struct Map {
    cspace: Option<Arc<CSpace>>,
    field: Option<Arc<MapField>>,
}

impl Map {
    fn new(lab: &Lab) -> Map {
        let info = &lab.info;
        let cspace = disc_cspace(&info.arena, &[], info.robot.radius_mm)
            .inspect_err(|e| warn!("no C-space for the lab's map: {e}"))
            .ok()
            .map(Arc::new);
        let field = cspace.as_deref().map(map_field).map(Arc::new);
        Map { cspace, field }
    }
}

/// Builds a definition's potential field on a blocking thread, one at a
/// time: a definition given while one is built waits in place of any
/// before it, so however many a client sends, the hub never waits and at
/// most one thread works.
struct FieldWorker {
    /// The number of the newest definition asked for.
    asked: u64,
    /// Whether a build is under way, and the newest waiting for it.
    busy: bool,
    waiting: Option<(u64, Vec<Shape>)>,
    done_tx: mpsc::UnboundedSender<(u64, Option<MapField>)>,
    done: mpsc::UnboundedReceiver<(u64, Option<MapField>)>,
}

impl FieldWorker {
    fn new() -> FieldWorker {
        let (done_tx, done) = mpsc::unbounded_channel();
        FieldWorker {
            asked: 0,
            busy: false,
            waiting: None,
            done_tx,
            done,
        }
    }

    /// Asks for the field of `virtual_obstacles` on `lab`'s map; what was
    /// asked before is forgotten.
    fn ask(&mut self, lab: &Lab, virtual_obstacles: Vec<Shape>) {
        self.asked += 1;
        self.waiting = Some((self.asked, virtual_obstacles));
        self.next(lab);
    }

    /// Starts the waiting build if none is under way.
    fn next(&mut self, lab: &Lab) {
        if self.busy {
            return;
        }
        let Some((number, shapes)) = self.waiting.take() else {
            return;
        };
        self.busy = true;
        let (arena, radius) = (lab.info.arena.clone(), lab.info.robot.radius_mm);
        let done = self.done_tx.clone();
        tokio::task::spawn_blocking(move || {
            let field = disc_cspace(&arena, &shapes, radius)
                .inspect_err(|e| warn!("no C-space for the definition: {e}"))
                .ok()
                .as_ref()
                .map(map_field);
            let _ = done.send((number, field));
        });
    }

    /// A build ended: its field if it is the newest asked for.
    fn finished(
        &mut self,
        lab: &Lab,
        number: u64,
        field: Option<MapField>,
    ) -> Option<Option<MapField>> {
        self.busy = false;
        self.next(lab);
        (number == self.asked).then_some(field)
    }

    /// Whatever is under way or waiting is no longer wanted.
    fn forget(&mut self) {
        self.asked += 1;
        self.waiting = None;
    }
}

impl Hub {
    pub(crate) fn new(lab: Lab, config: Arc<HostConfig>, supervisor: Supervisor) -> Hub {
        Hub {
            map: Map::new(&lab),
            lab,
            config,
            supervisor,
            clients: HashMap::new(),
            operator: None,
            resume: None,
            away: None,
            experiment: None,
            definition: None,
            last_event: 0,
            max_event_gap: 0,
            sync_violations: 0,
            last_command: Instant::now(),
            run: None,
            runs: 0,
            cspace: None,
            field: None,
            fields: FieldWorker::new(),
            readiness: Readiness::Ready,
            reset_run: None,
            reset_routes: mpsc::unbounded_channel(),
            stopper: None,
        }
    }

    pub(crate) async fn run(mut self, mut inbox: mpsc::Receiver<ToHub>) {
        let mut lease = tokio::time::interval(LEASE_CHECK);
        let mut status = self.lab.status.clone();
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
                    self.broadcast(&self.status());
                }
                Some(Finished(run, mut summary)) = self.lab.finished.recv() => {
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
                    self.run = None;
                    if self.supervisor.allows(Action::Finish) {
                        self.happened(Action::Finish);
                    }
                    summary.max_event_gap = self.max_event_gap;
                    summary.sync_violations = self.sync_violations;
                    summary.stopped_by = self.stopper.take().filter(|_| summary.reason == EndReason::EmergencyStop);
                    info!(run, reason = %summary.reason, reached_goal = summary.reached_goal, "run ended");
                    let reset = resets_after(summary.reason);
                    self.broadcast(&HostMessage::Done { summary });
                    if reset {
                        self.reset();
                    }
                }
                Some(route) = self.reset_routes.1.recv() => self.reset_planned(route),
                Some((number, field)) = self.fields.done.recv() => {
                    if let Some(field) = self.fields.finished(&self.lab, number, field) {
                        self.field = field.map(Arc::new);
                        self.happened(Action::FieldBuilt);
                    }
                }
                _ = lease.tick() => self.check_lease(),
                message = inbox.recv() => match message {
                    Some(ToHub::Join(id, out)) => {
                        self.clients.insert(id, Client { out, role: None });
                    }
                    Some(ToHub::Message(id, message)) => self.handle(id, message),
                    Some(ToHub::Leave(id, meant)) => self.leave(id, meant),
                    None => return,
                },
            }
            self.tell_state();
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
        self.send(id, error(code, message));
    }

    /// Sends to every welcomed client, encoded once.
    fn broadcast(&mut self, message: &HostMessage) {
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

    /// An operator who has sent no command for the lease time during a run
    /// loses the run and the role, and stays on as an observer.
    /// A run the Host itself steers along the defined path needs no
    /// commands: its operator is not silent for sending none (a lost one
    /// still ends it, through the connection's pings).
    fn check_lease(&mut self) {
        if self
            .away
            .as_ref()
            .is_some_and(|a| a.until <= Instant::now())
        {
            self.away = None;
            info!("the operator did not come back within the grace: the role is free");
            if self.supervisor.allows(Action::Stop) {
                self.lab
                    .request(LabRequest::Finish(EndReason::OperatorLeft));
            }
            self.release_operator();
        }
        let Some(id) = self.operator else { return };
        if !self.supervisor.allows(Action::Stop)
            || self.last_command.elapsed() < self.config.lease
            || self.host_follows()
        {
            return;
        }
        let lease = self.config.lease.as_secs_f64();
        info!(
            connection = id,
            "operator silent for {lease} s: the role is free"
        );
        self.lab
            .request(LabRequest::Finish(EndReason::OperatorSilent));
        self.release_operator();
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(Role::Observer);
        }
        self.refuse(
            id,
            ErrorCode::Timeout,
            format!("no command for {lease} s: the run ended and you watch now; say hello as operator to drive again"),
        );
    }

    /// Whether runs of what is mounted and defined follow a path on the Host.
    fn host_follows(&self) -> bool {
        match (self.experiment, &self.definition) {
            (Some(experiment), Some(definition)) => definition.host_follows(experiment),
            _ => false,
        }
    }

    /// The operator role is free again and the lab back to idle.
    fn release_operator(&mut self) {
        self.operator = None;
        self.resume = None;
        if self.supervisor.allows(Action::Release) {
            self.happened(Action::Release);
        }
        self.experiment = None;
        self.definition = None;
        self.cspace = None;
        self.field = None;
        self.fields.forget();
    }

    /// Tells every client what the supervisor fired since it last told,
    /// and logs each firing.
    fn tell_state(&mut self) {
        let Some(state) = self.supervisor.take_state() else {
            return;
        };
        for fired in &state.fired {
            info!(lab = fired.lab.id(), transition = %fired.transition, "fired");
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
        if self.experiment != Some(Experiment::Teleoperation) {
            return;
        }
        if virtual_obstacles.is_empty() {
            self.fields.forget();
            self.field = self.map.field.clone();
            self.happened(Action::FieldBuilt);
        } else {
            self.fields.ask(&self.lab, virtual_obstacles.to_vec());
        }
    }

    fn handle(&mut self, id: u64, message: GuestMessage) {
        let Some(role) = self.clients.get(&id).map(|c| c.role) else {
            return;
        };
        match (role, message) {
            (
                None,
                GuestMessage::Hello {
                    protocol,
                    role,
                    token,
                    resume,
                },
            ) => self.hello(id, protocol, role, token, resume),
            (None, _) => self.refuse(id, ErrorCode::HelloFirst, "send hello first"),
            // An observer (or an operator who lost the lease) may ask to drive.
            (
                Some(Role::Observer),
                GuestMessage::Hello {
                    protocol,
                    role: Role::Operator,
                    token,
                    resume,
                },
            ) => self.hello(id, protocol, Role::Operator, token, resume),
            (Some(_), GuestMessage::Hello { .. }) => {
                self.refuse(id, ErrorCode::NotAllowedNow, "already said hello")
            }
            // Anyone watching may stop the robot: safety before roles.
            (Some(_), GuestMessage::EmergencyStop) => self.emergency_stop(id),
            // Anyone watching may want to see the scene.
            (Some(_), GuestMessage::RequestFrame) => self.lab.request_frame(),
            (Some(Role::Observer), other) => self.refuse(
                id,
                ErrorCode::NotOperator,
                format!("observers watch; only the operator may {}", other.kind()),
            ),
            (Some(Role::Operator), message) => self.operate(id, message),
        }
    }

    fn hello(
        &mut self,
        id: u64,
        protocol: u32,
        role: Role,
        token: Option<String>,
        resume: Option<String>,
    ) {
        if protocol != PROTOCOL_VERSION {
            return self.refuse(
                id,
                ErrorCode::ProtocolMismatch,
                format!("this Host speaks protocol {PROTOCOL_VERSION}, not {protocol}"),
            );
        }
        if role == Role::Operator {
            if self.config.token.is_some() && token != self.config.token {
                let why = match token {
                    None => {
                        "this lab's operators need its token: say hello with it (vl guest --token), or watch as an observer"
                    }
                    Some(_) => "the operator token is wrong",
                };
                return self.refuse(id, ErrorCode::Unauthorized, why);
            }
            let returning = match &self.away {
                Some(away) if resume.as_deref() == Some(away.resume.as_str()) => true,
                Some(away) => {
                    let left = away.until.saturating_duration_since(Instant::now());
                    return self.refuse(
                        id,
                        ErrorCode::OperatorTaken,
                        format!(
                            "the operator's link dropped; the role is held for them for {:.0} more s",
                            left.as_secs_f64().ceil()
                        ),
                    );
                }
                None => false,
            };
            if self.operator.is_some() {
                return self.refuse(
                    id,
                    ErrorCode::OperatorTaken,
                    "another operator is driving; say hello again as an observer to watch",
                );
            }
            self.operator = Some(id);
            if returning {
                self.away = None;
                info!(connection = id, "the operator is back");
            }
            // Every welcome carries a fresh secret, so every drop has its
            // grace (and an old secret, once used, opens nothing).
            self.resume = Some(secret());
        }
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(role);
            let _ = client.out.try_send(ToConnection::Subscribe);
        }
        info!(connection = id, ?role, "welcomed");
        self.send(
            id,
            HostMessage::Welcome {
                session: id,
                role,
                experiments: self.config.experiments.iter().map(|e| e.info()).collect(),
                resume: (role == Role::Operator)
                    .then(|| self.resume.clone())
                    .flatten(),
            },
        );
        // A late observer catches up on what is mounted and defined.
        if let Some(mounted) = self.mounted() {
            self.send(id, mounted);
        }
        if let Some(definition) = self.definition.clone() {
            self.send(id, HostMessage::Defined { definition });
        }
        self.send(id, self.status());
        self.send(id, HostMessage::State(Box::new(self.supervisor.state())));
        // An operator back within the grace takes up the run where it stood.
        if role == Role::Operator && self.supervisor.allows(Action::Stop) {
            self.last_command = Instant::now();
            self.lab.request(LabRequest::Hold(false));
            self.send(
                id,
                HostMessage::Started {
                    event: self.last_event,
                },
            );
        }
    }

    fn mounted(&self) -> Option<HostMessage> {
        let info = &self.lab.info;
        self.experiment.map(|experiment| {
            HostMessage::Mounted(Box::new(MountedLab {
                experiment,
                arena: info.arena.clone(),
                robot: info.robot.clone(),
                camera: info.camera,
            }))
        })
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

    fn operate(&mut self, id: u64, message: GuestMessage) {
        match message {
            GuestMessage::Mount { experiment } => {
                let offered = &self.config.experiments;
                let Some(experiment) = Experiment::from_id(&experiment)
                    .ok()
                    .filter(|e| offered.contains(e))
                else {
                    let ids: Vec<&str> = offered.iter().map(|e| e.id()).collect();
                    return self.refuse(
                        id,
                        ErrorCode::UnknownExperiment,
                        format!(
                            "this Host has no experiment \"{experiment}\"; it offers {}",
                            ids.join(", ")
                        ),
                    );
                };
                if let Err(e) = self.supervisor.mount(experiment) {
                    return self.refuse(id, ErrorCode::NotAllowedNow, e.to_string());
                }
                self.experiment = Some(experiment);
                self.definition = None;
                if let Some(mounted) = self.mounted() {
                    self.broadcast(&mounted);
                }
                self.build_cspace();
            }
            GuestMessage::Define { definition } => {
                if !self.permitted(id, Action::Define) {
                    return;
                }
                if let Err(why) = definition.validate(&self.lab.info.arena, &self.lab.info.robot) {
                    return self.refuse(id, ErrorCode::InvalidDefinition, why.to_string());
                }
                if self.experiment == Some(Experiment::Navigation)
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
                self.supervise(id, Action::Define);
                self.definition = Some(definition.clone());
                self.broadcast(&HostMessage::Defined {
                    definition: definition.clone(),
                });
                // The path was checked against the C-space above.
                if self.experiment == Some(Experiment::Navigation) {
                    self.happened(Action::PathPlanned);
                }
                self.build_field(&definition.virtual_obstacles);
            }
            GuestMessage::Reset => {
                if self.supervisor.allows(Action::Stop) {
                    return self.refuse(
                        id,
                        ErrorCode::NotAllowedNow,
                        "a run is under way: stop it before the robot drives back to its start pose",
                    );
                }
                self.reset();
            }
            GuestMessage::Start => {
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
                if self.supervise(id, Action::Start)
                    && let Some(experiment) = self.experiment
                {
                    self.last_event = 0;
                    self.max_event_gap = 0;
                    self.sync_violations = 0;
                    self.last_command = Instant::now();
                    self.runs += 1;
                    self.run = Some(self.runs);
                    let definition = self.definition.clone().unwrap_or_default();
                    self.lab.request(LabRequest::Start {
                        run: self.runs,
                        definition,
                        experiment,
                        field: self.field.clone(),
                        face: None,
                    });
                    self.broadcast(&HostMessage::Started { event: 0 });
                }
            }
            GuestMessage::Stop => {
                if self.supervise(id, Action::Stop) {
                    // The lab answers with the run's summary; `done` follows.
                    self.lab.request(LabRequest::Finish(EndReason::Stopped));
                }
            }
            GuestMessage::Command { event, seen, drive } => {
                if !self.permitted(id, Action::Command) {
                    return;
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
                self.lab.request(LabRequest::Drive { event, drive });
            }
            GuestMessage::Hello { .. }
            | GuestMessage::EmergencyStop
            | GuestMessage::RequestFrame
            | GuestMessage::Ping { .. }
            | GuestMessage::Pong { .. }
            | GuestMessage::Bye => {}
        }
    }

    /// Stops the running robot at once and ends the run; the next run needs
    /// the operator's Start.
    fn emergency_stop(&mut self, id: u64) {
        warn!(connection = id, "emergency stop");
        if self.supervisor.allows(Action::Stop) {
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

    /// The status every client is told: the devices, and whether a run may start.
    fn status(&self) -> HostMessage {
        self.lab.status.borrow().message(self.readiness)
    }

    fn set_readiness(&mut self, readiness: Readiness) {
        if self.readiness != readiness {
            self.readiness = readiness;
            self.broadcast(&self.status());
        }
    }

    /// Makes the lab ready for the next run, as remote labs reset their
    /// equipment between users: unless the robot is at the start pose
    /// already, a route back is planned off the hub on the lab's map, then
    /// driven like any run (followed, braked by the safety layer), turning
    /// at the end to the start heading. Start waits until it is there.
    fn reset(&mut self) {
        if !self.config.reset || self.run.is_some() || self.readiness == Readiness::GettingReady {
            return;
        }
        let Some(pose) = self.robot_pose() else {
            return;
        };
        let start = self.lab.info.arena.start;
        let turn = wrap_angle(pose.theta_rad - start.theta_rad).abs();
        if pose.point().distance(start.point()) <= AT_START_MM && turn <= AT_START_RAD {
            return;
        }
        info!("the lab is getting ready: the robot drives back to its start pose");
        self.set_readiness(Readiness::GettingReady);
        let (arena, robot) = (self.lab.info.arena.clone(), self.lab.info.robot.clone());
        let routes = self.reset_routes.0.clone();
        tokio::task::spawn_blocking(move || {
            let goal = Goal {
                tolerance_mm: AT_START_MM,
                ..Goal::at(start.point())
            };
            let path = if pose.point().distance(start.point()) <= goal.tolerance_mm {
                Ok(Vec::new())
            } else {
                plan_route(&arena, &[], &robot, pose, start.point()).map(|plan| plan.points())
            };
            let route = path
                .map(|path| Definition {
                    goal: Some(goal),
                    path,
                    time_limit_s: Some(RESET_LIMIT_S),
                    ..Definition::default()
                })
                .map_err(|e| e.to_string());
            let _ = routes.send(route);
        });
    }

    /// Where the lab's newest feedback puts the robot.
    fn robot_pose(&self) -> Option<Pose> {
        match &*self.lab.feedback.borrow() {
            Some(HostMessage::Feedback { pose, .. }) => Some(*pose),
            _ => None,
        }
    }

    /// The route back to the start pose is planned: drive it.
    fn reset_planned(&mut self, route: ResetRoute) {
        // An emergency stop while planning, or a run since, called it off.
        if self.readiness != Readiness::GettingReady || self.run.is_some() {
            return;
        }
        match route {
            Ok(definition) => {
                self.runs += 1;
                self.reset_run = Some(self.runs);
                self.lab.request(LabRequest::Start {
                    run: self.runs,
                    definition,
                    experiment: Experiment::Navigation,
                    field: None,
                    face: Some(self.lab.info.arena.start.theta_rad),
                });
            }
            Err(why) => {
                warn!("no way back to the start pose ({why}): runs start where the robot stands");
                self.set_readiness(Readiness::Ready);
            }
        }
    }

    /// The drive back to the start pose ended: the lab is ready.
    fn reset_done(&mut self, summary: &vl_core::Summary) {
        self.reset_run = None;
        if summary.reason == EndReason::GoalReached {
            info!(
                seconds = summary.seconds,
                "the robot is back at its start pose: the lab is ready"
            );
        } else {
            warn!(reason = %summary.reason, "the drive back to the start pose ended short: runs start where the robot stands");
        }
        self.set_readiness(Readiness::Ready);
    }

    /// A connection closed: if it was the operator, the robot stops; the
    /// lab returns to idle for the next person at once if they meant to leave,
    /// or after the grace if their link dropped and they do not come back.
    fn leave(&mut self, id: u64, meant: bool) {
        self.clients.remove(&id);
        if self.operator != Some(id) {
            return;
        }
        info!(connection = id, "operator left");
        let running = self.supervisor.allows(Action::Stop);
        // A link that dropped may come back: the role and the run are held
        // for the grace, the robot still; a lab with nothing on it is free.
        if let Some(resume) = self.resume.take()
            && !meant
            && !self.config.grace.is_zero()
            && self.experiment.is_some()
        {
            self.operator = None;
            self.away = Some(Away {
                resume,
                until: Instant::now() + self.config.grace,
            });
            if running {
                self.lab.request(LabRequest::Hold(true));
            }
            return;
        }
        // A run the operator could stop is stopped for them.
        if running {
            self.lab
                .request(LabRequest::Finish(EndReason::OperatorLeft));
        }
        self.release_operator();
    }
}
