//! The Host's side of the Media: a WebSocket server speaking protocol v1.
//!
//! One task per connection reads and writes its socket; one hub task owns
//! the session (who is operator, the supervisor net, the current
//! definition) and is the only place that changes it, so there are no locks
//! around session state. Feedback and frames bypass the hub: every
//! connection watches the lab's newest values directly.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::{self, Message};
use tracing::{debug, info, warn};
use vl_core::{
    Action, Definition, EndReason, ErrorCode, Experiment, GuestMessage, HostMessage,
    MAX_FRAME_BYTES, MAX_TEXT_BYTES, Named, PROTOCOL_VERSION, Role, Supervisor, Wire,
};

use crate::lab::{Finished, Lab, LabRequest};

/// How often the Host measures each connection's round-trip time.
const PING_EVERY: Duration = Duration::from_secs(1);

/// How the Host admits people.
#[derive(Debug, Clone)]
pub struct HostConfig {
    /// When set, an operator's `hello` must carry this token.
    pub token: Option<String>,
    /// What the lab offers, in the order Guests list it.
    pub experiments: Vec<Experiment>,
}

impl Default for HostConfig {
    fn default() -> Self {
        HostConfig {
            token: None,
            experiments: Experiment::ALL.to_vec(),
        }
    }
}

/// Accepts connections on `listener` and serves the lab until the task is dropped.
pub async fn serve(listener: TcpListener, lab: Lab, config: HostConfig) {
    let (hub_tx, hub_rx) = mpsc::unbounded_channel();
    let feedback = lab.feedback.clone();
    let frames = lab.frames.clone();
    let hub = Hub {
        lab,
        config,
        supervisor: Supervisor::new(),
        clients: HashMap::new(),
        operator: None,
        experiment: None,
        definition: None,
        last_event: 0,
    };
    // The hub lives exactly as long as the server: dropping this future
    // drops the lab, which stops the robot.
    tokio::select! {
        () = hub.run(hub_rx) => {}
        () = accept(listener, hub_tx, feedback, frames) => {}
    }
}

async fn accept(
    listener: TcpListener,
    hub_tx: mpsc::UnboundedSender<ToHub>,
    feedback: tokio::sync::watch::Receiver<Option<HostMessage>>,
    frames: tokio::sync::watch::Receiver<Option<tungstenite::Bytes>>,
) {
    let mut next_id = 1u64;
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            Err(e) => {
                warn!("accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let id = next_id;
        next_id += 1;
        let connection = Connection {
            id,
            hub: hub_tx.clone(),
            feedback: feedback.clone(),
            frames: frames.clone(),
        };
        tokio::spawn(async move {
            if let Err(e) = connection.run(stream).await {
                debug!(%peer, "connection {id} ended: {e}");
            }
        });
    }
}

/// What a connection tells the hub.
enum ToHub {
    Join(u64, mpsc::UnboundedSender<ToConnection>),
    Message(u64, GuestMessage),
    Leave(u64),
}

/// What the hub tells a connection.
enum ToConnection {
    Send(Box<HostMessage>),
    /// The client was welcomed: start streaming feedback and frames.
    Subscribe,
}

struct Connection {
    id: u64,
    hub: mpsc::UnboundedSender<ToHub>,
    feedback: tokio::sync::watch::Receiver<Option<HostMessage>>,
    frames: tokio::sync::watch::Receiver<Option<tungstenite::Bytes>>,
}

impl Connection {
    async fn run(mut self, stream: TcpStream) -> Result<(), tungstenite::Error> {
        let _ = stream.set_nodelay(true);
        let config = WebSocketConfig::default()
            .max_message_size(Some(MAX_TEXT_BYTES.max(MAX_FRAME_BYTES)))
            .max_frame_size(Some(MAX_TEXT_BYTES.max(MAX_FRAME_BYTES)));
        let ws = tokio_tungstenite::accept_async_with_config(stream, Some(config)).await?;
        let (mut sink, mut source) = ws.split();
        let (to_me, mut inbox) = mpsc::unbounded_channel();
        let _ = self.hub.send(ToHub::Join(self.id, to_me));
        let clock = Instant::now();
        let mut ping = tokio::time::interval(PING_EVERY);
        let mut subscribed = false;
        let result = loop {
            tokio::select! {
                incoming = source.next() => match incoming {
                    None | Some(Ok(Message::Close(_))) => break Ok(()),
                    Some(Ok(Message::Text(text))) => {
                        match GuestMessage::decode(text.as_str()) {
                            Ok(GuestMessage::Ping { t }) => {
                                sink.send(text_of(&HostMessage::Pong { t })).await?;
                            }
                            Ok(GuestMessage::Pong { t }) => {
                                let rtt_ms = clock.elapsed().as_secs_f64() * 1e3 - t;
                                debug!(connection = self.id, rtt_ms, "round trip");
                            }
                            Ok(GuestMessage::Bye) => break Ok(()),
                            Ok(message) => {
                                let _ = self.hub.send(ToHub::Message(self.id, message));
                            }
                            Err(e) => {
                                sink.send(text_of(&error(e.code(), e.to_string()))).await?;
                            }
                        }
                    }
                    Some(Ok(Message::Binary(_))) => {
                        let reply = error(ErrorCode::BadMessage, "binary messages flow only from Host to Guest");
                        sink.send(text_of(&reply)).await?;
                    }
                    Some(Ok(_)) => {} // WebSocket pings are answered by tungstenite
                    Some(Err(tungstenite::Error::Capacity(e))) => {
                        // The rest of that message cannot be skipped: say why, then close.
                        let reply = error(ErrorCode::TooLarge, format!("message too large: {e}"));
                        let _ = sink.send(text_of(&reply)).await;
                        let _ = sink.send(Message::Close(None)).await;
                        break Ok(());
                    }
                    Some(Err(e)) => break Err(e),
                },
                Some(out) = inbox.recv() => match out {
                    ToConnection::Send(message) => sink.send(text_of(&message)).await?,
                    ToConnection::Subscribe => {
                        subscribed = true;
                        self.feedback.mark_changed();
                        self.frames.mark_changed();
                    }
                },
                Ok(()) = self.feedback.changed(), if subscribed => {
                    let latest = self.feedback.borrow_and_update().clone();
                    if let Some(message) = latest {
                        sink.send(text_of(&message)).await?;
                    }
                }
                Ok(()) = self.frames.changed(), if subscribed => {
                    let latest = self.frames.borrow_and_update().clone();
                    if let Some(frame) = latest {
                        sink.send(Message::Binary(frame)).await?;
                    }
                }
                () = self.hub.closed() => {
                    let _ = sink.send(text_of(&HostMessage::Bye)).await;
                    let _ = sink.send(Message::Close(None)).await;
                    break Ok(());
                }
                _ = ping.tick() => {
                    let t = clock.elapsed().as_secs_f64() * 1e3;
                    sink.send(text_of(&HostMessage::Ping { t })).await?;
                }
            }
        };
        let _ = self.hub.send(ToHub::Leave(self.id));
        result
    }
}

fn text_of(message: &HostMessage) -> Message {
    Message::text(message.encode())
}

fn error(code: ErrorCode, message: impl Into<String>) -> HostMessage {
    HostMessage::Error {
        code,
        message: message.into(),
    }
}

struct Client {
    out: mpsc::UnboundedSender<ToConnection>,
    role: Option<Role>,
}

/// The one owner of session state.
struct Hub {
    lab: Lab,
    config: HostConfig,
    supervisor: Supervisor,
    clients: HashMap<u64, Client>,
    operator: Option<u64>,
    /// The mounted experiment.
    experiment: Option<Experiment>,
    definition: Option<Definition>,
    /// Event number of the last command accepted in this run.
    last_event: u64,
}

impl Hub {
    async fn run(mut self, mut inbox: mpsc::UnboundedReceiver<ToHub>) {
        loop {
            tokio::select! {
                message = inbox.recv() => match message {
                    Some(ToHub::Join(id, out)) => {
                        self.clients.insert(id, Client { out, role: None });
                    }
                    Some(ToHub::Message(id, message)) => self.handle(id, message),
                    Some(ToHub::Leave(id)) => self.leave(id),
                    None => return,
                },
                Some(Finished(summary)) = self.lab.finished.recv() => {
                    if self.supervisor.allows(Action::Finish) {
                        let _ = self.supervisor.fire(Action::Finish);
                    }
                    info!(reason = ?summary.reason, reached_goal = summary.reached_goal, "run ended");
                    self.broadcast(&HostMessage::Done { summary });
                }
            }
        }
    }

    fn send(&self, id: u64, message: HostMessage) {
        if let Some(client) = self.clients.get(&id) {
            let _ = client.out.send(ToConnection::Send(Box::new(message)));
        }
    }

    fn refuse(&self, id: u64, code: ErrorCode, message: impl Into<String>) {
        self.send(id, error(code, message));
    }

    /// Sends to every welcomed client.
    fn broadcast(&self, message: &HostMessage) {
        for client in self.clients.values().filter(|c| c.role.is_some()) {
            let _ = client
                .out
                .send(ToConnection::Send(Box::new(message.clone())));
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
                },
            ) => self.hello(id, protocol, role, token),
            (None, _) => self.refuse(id, ErrorCode::HelloFirst, "send hello first"),
            (Some(_), GuestMessage::Hello { .. }) => {
                self.refuse(id, ErrorCode::NotAllowedNow, "already said hello")
            }
            // Anyone watching may stop the robot: safety before roles.
            (Some(_), GuestMessage::EmergencyStop) => self.emergency_stop(id),
            (Some(Role::Observer), other) => self.refuse(
                id,
                ErrorCode::NotOperator,
                format!("observers watch; only the operator may {}", other.kind()),
            ),
            (Some(Role::Operator), message) => self.operate(id, message),
        }
    }

    fn hello(&mut self, id: u64, protocol: u32, role: Role, token: Option<String>) {
        if protocol != PROTOCOL_VERSION {
            return self.refuse(
                id,
                ErrorCode::ProtocolMismatch,
                format!("this Host speaks protocol {PROTOCOL_VERSION}, not {protocol}"),
            );
        }
        if role == Role::Operator {
            if self.config.token.is_some() && token != self.config.token {
                return self.refuse(id, ErrorCode::Unauthorized, "the operator token is wrong");
            }
            if self.operator.is_some() {
                return self.refuse(
                    id,
                    ErrorCode::OperatorTaken,
                    "another operator is driving; say hello again as an observer to watch",
                );
            }
            self.operator = Some(id);
        }
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(role);
            let _ = client.out.send(ToConnection::Subscribe);
        }
        info!(connection = id, ?role, "welcomed");
        self.send(
            id,
            HostMessage::Welcome {
                session: id,
                role,
                experiments: self.config.experiments.iter().map(|e| e.info()).collect(),
            },
        );
        // A late observer catches up on what is mounted and defined.
        if let Some(mounted) = self.mounted() {
            self.send(id, mounted);
        }
        if let Some(definition) = self.definition.clone() {
            self.send(id, HostMessage::Defined { definition });
        }
    }

    fn mounted(&self) -> Option<HostMessage> {
        let info = &self.lab.info;
        self.experiment.map(|experiment| HostMessage::Mounted {
            experiment,
            arena: info.arena.clone(),
            robot: info.robot.clone(),
            camera: info.camera,
        })
    }

    /// Whether the supervisor enables `action` now; if not, tells the
    /// operator why.
    fn permitted(&self, id: u64, action: Action) -> bool {
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
                if self.supervise(id, Action::Mount) {
                    self.experiment = Some(experiment);
                    self.definition = None;
                    if let Some(mounted) = self.mounted() {
                        self.broadcast(&mounted);
                    }
                }
            }
            GuestMessage::Define { definition } => {
                if !self.permitted(id, Action::Define) {
                    return;
                }
                if let Err(why) = definition.validate(&self.lab.info.arena, &self.lab.info.robot) {
                    return self.refuse(id, ErrorCode::InvalidDefinition, why);
                }
                self.supervise(id, Action::Define);
                self.definition = Some(definition.clone());
                self.broadcast(&HostMessage::Defined { definition });
            }
            GuestMessage::Start => {
                if self.supervise(id, Action::Start)
                    && let Some(experiment) = self.experiment
                {
                    self.last_event = 0;
                    let definition = self.definition.clone().unwrap_or_default();
                    self.lab.request(LabRequest::Start {
                        definition,
                        experiment,
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
            GuestMessage::Command { event, drive } => {
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
                self.last_event = event;
                self.lab.request(LabRequest::Drive { event, drive });
            }
            GuestMessage::Hello { .. }
            | GuestMessage::EmergencyStop
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
            self.lab
                .request(LabRequest::Finish(EndReason::EmergencyStop));
        }
    }

    /// A connection closed: if it was the operator, the robot stops and the
    /// lab returns to idle for the next person.
    fn leave(&mut self, id: u64) {
        self.clients.remove(&id);
        if self.operator != Some(id) {
            return;
        }
        self.operator = None;
        info!(connection = id, "operator left");
        // A run the operator could stop is stopped for them.
        if self.supervisor.allows(Action::Stop) {
            self.lab
                .request(LabRequest::Finish(EndReason::OperatorLeft));
        }
        if self.supervisor.allows(Action::Release) {
            let _ = self.supervisor.fire(Action::Release);
        }
        self.experiment = None;
        self.definition = None;
    }
}
