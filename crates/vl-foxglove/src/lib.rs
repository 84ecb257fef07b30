//! Live in Foxglove and Lichtblick: the Foxglove WebSocket protocol on the
//! Host's own port, told apart from a Guest by its subprotocol. A Foxglove
//! client watches like any observer (the same gate, the same places to
//! watch from) and gets the channels a run's recording has, in the same
//! schemas, made once for all clients (`feed`). It may also drive, as the
//! operator, through services and a Twist on `/cmd_vel` (`drive`).
//!
//! Written here rather than with Foxglove's SDK (crate `foxglove`): the
//! SDK runs a server of its own on its own listener, with its own TLS
//! (aws-lc-rs) and admission; here the lab's port, TLS, admission and
//! gate stay one, and the views are the recorder's own.
//!
//! It plugs into the Host as an extension (`Foxglove`): a WebSocket
//! protocol on the lab's port, and the task that makes the views.

mod drive;
mod feed;
mod ops;
mod subprotocol;

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use tokio::sync::broadcast;
use tokio_tungstenite::tungstenite::protocol::CloseFrame;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::{Bytes, Message};
use vl_core::{ErrorCode, GuestMessage, HostMessage, PROTOCOL_VERSION, Role, Wire};
use vl_record::{Topic, View, now_ns};

use drive::{CMD_VEL, SERVICES};
use feed::{LiveFeed, Sources};
use subprotocol::Subprotocol;
use vl_host::hub::{OUTBOX, ToConnection, ToHub};
use vl_host::socket::{self, Sink, Socket};
use vl_host::{
    Bucket, Credentials, Extension, ExtensionTask, Gate, LabHandle, Pacer, Purpose, SocketClient,
    SocketProtocol, Ticket, Watching,
};

/// Foxglove's live server on the lab's port. At a gateway, whose lab is
/// its cells, it has no views: Foxglove connects to a cell's own Host.
#[derive(Default)]
pub struct Foxglove {
    /// The lab's views, made once for every client, from the lab's start.
    feed: OnceLock<LiveFeed>,
}

impl std::fmt::Debug for Foxglove {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Foxglove")
    }
}

impl Extension for Foxglove {
    fn socket_protocol(&self, offered: &str) -> Option<SocketProtocol> {
        Subprotocol::chosen(offered).map(|chosen| SocketProtocol {
            name: chosen.name(),
            max_message: MAX_MESSAGE,
        })
    }

    fn serve_socket(self: Arc<Self>, mut socket: Socket, client: SocketClient) -> ExtensionTask {
        Box::pin(async move {
            match self.feed.get() {
                Some(feed) => Watcher::new(client, feed.clone()).serve(socket).await,
                None => {
                    let why = "Foxglove connects to a cell's own Host, not to the gateway";
                    let frame = CloseFrame {
                        code: CloseCode::Policy,
                        reason: why.into(),
                    };
                    let _ = socket.close(Some(frame)).await;
                }
            }
        })
    }

    /// Makes the lab's views from its start, for as long as it runs.
    fn run(self: Arc<Self>, lab: LabHandle) -> ExtensionTask {
        let Some(scene) = lab.scene.clone() else {
            return Box::pin(std::future::pending());
        };
        let (feed, making) = LiveFeed::start(Sources {
            scene,
            since_ns: lab.since_ns,
            feedback: lab.feedback.clone(),
            frames: lab.frames.clone(),
            log: lab.log.clone(),
            live: lab.live.listen(),
        });
        // Set, and listening to the hub, before the lab takes its first
        // connection or its hub says anything: `run` is called as the lab
        // starts (`run_extensions`), the feed's task polled after.
        let _ = self.feed.set(feed);
        Box::pin(making)
    }
}
use ops::{CHANNELS, ClientOp, ServiceCall, StatusLevel, status};

/// Subscriptions one client may hold, and channels it may advertise.
const MAX_SUBSCRIPTIONS: usize = 64;
const MAX_CLIENT_CHANNELS: usize = 16;
/// The largest message a Foxglove client may send (a subscribe to every
/// channel is a few hundred bytes).
const MAX_MESSAGE: usize = 64 << 10;
/// How often the Host pings a Foxglove client (WebSocket pings, which
/// every client answers by itself), and tells it the time.
const PING_EVERY: Duration = Duration::from_secs(1);
const TIME_EVERY: Duration = Duration::from_millis(100);
/// Ops a client may send a second, and in a burst (a Guest's rates): past
/// them, the client is not read until it is within them again.
const OPS_PER_S: f64 = 200.0;
const OPS_BURST: f64 = 400.0;
/// Bytes a client may be sent a second, and in a burst: a camera, the
/// scene, the path and every number, several times over. What passes it
/// is not sent (newest-only, as a slow link gets fewer frames): a client
/// subscribing again and again to the lab's largest channels draws no
/// more than this.
const BYTES_OUT_PER_S: f64 = 4.0 * 1024.0 * 1024.0;
const BYTES_OUT_BURST: f64 = 8.0 * 1024.0 * 1024.0;

/// Writes `message` in time, or the client is let go (`Err`).
async fn put(sink: &mut Sink, message: Message) -> Result<(), ()> {
    socket::write(sink, message).await.map_err(|_| ())
}

/// Why a connection ends, as its close frame says.
enum Ending {
    /// The client closed, or is let go: 1000.
    Normal,
    /// The Host is stopping: 1001.
    Away,
}

/// One client's subscriptions, channels and driving.
struct Client {
    /// Subscription ids by channel.
    subscribed: HashMap<Topic, Vec<u32>>,
    /// The client's `/cmd_vel` channels.
    cmd_vel: HashSet<u32>,
    advertised: usize,
    /// What it may still be sent now.
    out: Bucket,
    driver: Pacer,
}

impl Client {
    fn wants(&self, topic: Topic) -> bool {
        self.subscribed
            .get(&topic)
            .is_some_and(|ids| !ids.is_empty())
    }

    fn holds(&self, id: u32) -> bool {
        self.subscribed.values().any(|ids| ids.contains(&id))
    }

    fn subscriptions(&self) -> usize {
        self.subscribed.values().map(Vec::len).sum()
    }

    fn watches_camera(&self) -> bool {
        self.wants(Topic::Camera) || self.wants(Topic::Annotations)
    }

    /// Sends `view` on every subscription to its channel, within budget.
    async fn send(&mut self, sink: &mut Sink, view: &View) -> Result<(), ()> {
        for &id in self.subscribed.get(&view.topic).into_iter().flatten() {
            send_within(&mut self.out, sink, id, view).await?;
        }
        Ok(())
    }
}

/// Sends `view` on subscription `id` within the client's budget `out`;
/// past it, the message is not sent.
async fn send_within(out: &mut Bucket, sink: &mut Sink, id: u32, view: &View) -> Result<(), ()> {
    let message = ops::data(id, view);
    let bytes = message.len() as f64;
    if !out.take(bytes).is_zero() {
        out.refund(bytes);
        return Ok(());
    }
    put(sink, message).await
}

/// A Foxglove client's connection, and what it takes from the lab.
struct Watcher {
    id: u64,
    hub: tokio::sync::mpsc::Sender<ToHub>,
    feed: LiveFeed,
    feedback: tokio::sync::watch::Receiver<Option<HostMessage>>,
    watchers: Arc<std::sync::atomic::AtomicUsize>,
    gate: Arc<Gate>,
    peer: std::net::SocketAddr,
    ticket: Ticket,
    ping_timeout: Duration,
    /// One per Host start.
    session: String,
    /// What the lab offers: what its mount service may be asked for.
    experiments: Arc<[vl_core::Experiment]>,
}

impl Watcher {
    fn new(client: SocketClient, feed: LiveFeed) -> Watcher {
        Watcher {
            id: client.id,
            hub: client.lab.hub,
            feed,
            feedback: client.lab.feedback,
            watchers: client.lab.watchers,
            experiments: client.lab.experiments,
            gate: client.lab.gate,
            peer: client.peer,
            ticket: client.ticket,
            ping_timeout: client.ping_timeout,
            session: client.lab.since_ns.to_string(),
        }
    }

    /// Serves a Foxglove client until it leaves or cannot be served.
    async fn serve(mut self, socket: Socket) {
        let (mut sink, mut source) = socket.split();
        let anyone = Credentials {
            role: Role::Observer,
            user: None,
            password: None,
            token: None,
            session: None,
            purpose: Purpose::Session,
        };
        let admitted = match self.gate.check(self.id, self.peer.ip(), anyone).await {
            Ok(admitted) if self.ticket.seat(admitted.may_drive) => admitted,
            Ok(_) => {
                let why = "the lab is full: every place to watch from is taken";
                let _ = put(&mut sink, status(StatusLevel::Error, why)).await;
                return close(&mut sink, Ending::Normal).await;
            }
            Err(refused) => {
                let _ = put(&mut sink, status(StatusLevel::Error, &refused.why)).await;
                return close(&mut sink, Ending::Normal).await;
            }
        };
        let (to_me, mut inbox) = tokio::sync::mpsc::channel(OUTBOX);
        if self
            .hub
            .send(ToHub::Join(self.id, to_me, None))
            .await
            .is_err()
        {
            return close(&mut sink, Ending::Away).await;
        }
        let hello = ToHub::Hello {
            id: self.id,
            admitted,
            protocol: PROTOCOL_VERSION,
            role: Role::Observer,
            resume: None,
        };
        let ending = if self.hub.send(hello).await.is_ok() {
            self.watch(&mut sink, &mut source, &mut inbox).await
        } else {
            Ending::Away
        };
        let _ = self.hub.send(ToHub::Leave(self.id, true)).await;
        close(&mut sink, ending).await;
    }

    async fn watch(
        &mut self,
        sink: &mut Sink,
        source: &mut futures_util::stream::SplitStream<Socket>,
        inbox: &mut tokio::sync::mpsc::Receiver<ToConnection>,
    ) -> Ending {
        for opening in [
            ops::server_info(&self.session),
            ops::advertise(),
            drive::advertise_services(&self.experiments),
        ] {
            if put(sink, opening).await.is_err() {
                return Ending::Normal;
            }
        }
        let mut views = self.feed.subscribe();
        let mut client = Client {
            subscribed: HashMap::new(),
            cmd_vel: HashSet::new(),
            advertised: 0,
            out: Bucket::new(BYTES_OUT_PER_S, BYTES_OUT_BURST),
            driver: Pacer::default(),
        };
        let ending = self
            .serve_client(sink, source, inbox, &mut views, &mut client)
            .await;
        if client.watches_camera() {
            self.feed.watch_camera(false);
        }
        ending
    }

    async fn serve_client(
        &mut self,
        sink: &mut Sink,
        source: &mut futures_util::stream::SplitStream<Socket>,
        inbox: &mut tokio::sync::mpsc::Receiver<ToConnection>,
        views: &mut broadcast::Receiver<std::sync::Arc<View>>,
        client: &mut Client,
    ) -> Ending {
        let mut ops = Bucket::new(OPS_PER_S, OPS_BURST);
        let mut paused_until: Option<tokio::time::Instant> = None;
        let mut watching = None;
        let mut ping = tokio::time::interval(PING_EVERY);
        let mut clock = tokio::time::interval(TIME_EVERY);
        let mut heard = Instant::now();
        let mut evicted = self.ticket.evicted.clone();
        loop {
            let sent = tokio::select! {
                () = async { tokio::time::sleep_until(paused_until.unwrap_or_else(tokio::time::Instant::now)).await }, if paused_until.is_some() => {
                    paused_until = None;
                    Ok(())
                }
                incoming = source.next(), if paused_until.is_none() => match incoming {
                    Some(Ok(Message::Close(_))) | Some(Err(_)) | None => return Ending::Normal,
                    Some(Ok(message)) => {
                        heard = Instant::now();
                        // Over its rate, the client is not read for a while:
                        // its own socket holds it back.
                        let wait = ops.take(1.0);
                        if !wait.is_zero() {
                            paused_until = Some(tokio::time::Instant::now() + wait);
                        }
                        self.heard(sink, client, message).await
                    }
                },
                view = views.recv(), if watching.is_some() => match view {
                    Ok(view) => client.send(sink, &view).await,
                    // A client that fell behind skips to the newest.
                    Err(broadcast::error::RecvError::Lagged(_)) => Ok(()),
                    Err(broadcast::error::RecvError::Closed) => return Ending::Away,
                },
                out = inbox.recv() => match out {
                    Some(ToConnection::Send(message)) => self.hub_said(sink, client, &message).await,
                    Some(ToConnection::End(_, why)) => {
                        let _ = put(sink, status(StatusLevel::Error, &why)).await;
                        return Ending::Normal;
                    }
                    Some(ToConnection::Subscribe | ToConnection::Watch(_)) => {
                        watching.get_or_insert_with(|| Watching::new(&self.watchers));
                        self.ticket.welcomed();
                        Ok(())
                    }
                    // The hub let go of this client: it is gone, or the
                    // client fell too far behind.
                    None if self.hub.is_closed() => return Ending::Away,
                    None => {
                        let _ = put(sink, status(StatusLevel::Error, ErrorCode::SlowReader.to_string().as_str())).await;
                        return Ending::Normal;
                    }
                },
                Ok(()) = self.feedback.changed(), if client.driver.operator() => {
                    let event = match &*self.feedback.borrow_and_update() {
                        Some(HostMessage::Feedback(feedback)) => Some(feedback.event),
                        _ => None,
                    };
                    match event.and_then(|event| client.driver.feedback(event)) {
                        Some(command) => self.tell_hub(command).await,
                        None => Ok(()),
                    }
                }
                Ok(()) = evicted.changed() => {
                    if *evicted.borrow() {
                        return Ending::Normal;
                    }
                    Ok(())
                }
                () = self.hub.closed() => return Ending::Away,
                _ = clock.tick(), if watching.is_some() => put(sink, ops::time(now_ns())).await,
                _ = ping.tick() => {
                    if heard.elapsed() > self.ping_timeout {
                        return Ending::Normal;
                    }
                    put(sink, Message::Ping(Bytes::new())).await
                }
            };
            if sent.is_err() {
                return Ending::Normal;
            }
        }
    }

    async fn tell_hub(&self, message: GuestMessage) -> Result<(), ()> {
        self.hub
            .send(ToHub::Message(self.id, message))
            .await
            .map_err(|_| ())
    }

    /// What the hub told this client: its errors as statuses, and what
    /// its driving needs to know.
    async fn hub_said(
        &self,
        sink: &mut Sink,
        client: &mut Client,
        message: &Message,
    ) -> Result<(), ()> {
        let Message::Text(json) = message else {
            return Ok(());
        };
        let Ok(message) = HostMessage::decode(json.as_str()) else {
            return Ok(());
        };
        client.driver.heard(&message);
        match message {
            HostMessage::Error { code, message } => {
                put(
                    sink,
                    status(StatusLevel::Error, &format!("{code}: {message}")),
                )
                .await
            }
            HostMessage::Role { role, ended, .. } => {
                let text = match (role, ended) {
                    (Role::Operator, _) => {
                        "you are the operator: call /vl/mount and /vl/start, then drive on /cmd_vel"
                            .to_owned()
                    }
                    (_, Some(why)) => format!("you are no longer the operator: {why}"),
                    _ => "you are watching".to_owned(),
                };
                put(sink, status(StatusLevel::Info, &text)).await
            }
            _ => Ok(()),
        }
    }

    /// Takes what the client sent.
    async fn heard(
        &self,
        sink: &mut Sink,
        client: &mut Client,
        message: Message,
    ) -> Result<(), ()> {
        match message {
            Message::Text(op) => self.op(sink, client, op.as_str()).await,
            Message::Binary(bytes) => match bytes.first() {
                Some(&ops::CLIENT_MESSAGE_DATA) => self.published(sink, client, &bytes).await,
                Some(&ops::SERVICE_CALL_REQUEST) => match ServiceCall::parse(&bytes) {
                    Some(call) => self.call(sink, &call).await,
                    None => put(sink, status(StatusLevel::Error, "a service call request too short for its lengths")).await,
                },
                _ => put(sink, status(StatusLevel::Warning, "unknown binary opcode: this server takes client messages (1) and service calls (2)")).await,
            },
            _ => Ok(()),
        }
    }

    /// A message on one of the client's channels: a Twist on `/cmd_vel`.
    async fn published(
        &self,
        sink: &mut Sink,
        client: &mut Client,
        bytes: &Bytes,
    ) -> Result<(), ()> {
        let Some((channel, payload)) = ops::client_data(bytes) else {
            return put(
                sink,
                status(
                    StatusLevel::Error,
                    "a client message too short for its channel id",
                ),
            )
            .await;
        };
        if !client.cmd_vel.contains(&channel) {
            let why = format!(
                "channel {channel} is not {CMD_VEL} in json: only Twists on {CMD_VEL} may be published"
            );
            return put(sink, status(StatusLevel::Error, &why)).await;
        }
        if !client.driver.operator() {
            let why = format!(
                "only the operator drives: call {} first (as the account that may drive, at a lab with accounts)",
                drive::CONTROL
            );
            return put(sink, status(StatusLevel::Error, &why)).await;
        }
        match drive::twist(&payload) {
            Ok(drive) => match client.driver.drive(drive) {
                Some(command) => self.tell_hub(command).await,
                None => Ok(()),
            },
            Err(why) => put(sink, status(StatusLevel::Error, &why)).await,
        }
    }

    /// A service call: taken to the hub as a Guest's message would be.
    async fn call(&self, sink: &mut Sink, call: &ServiceCall) -> Result<(), ()> {
        let Some(&service) = SERVICES.get(call.service as usize) else {
            let why = format!("no service {}", call.service);
            return put(sink, ops::service_failure(call, &why)).await;
        };
        if call.encoding != "json" {
            let why = format!("requests are json, not {}", call.encoding);
            return put(sink, ops::service_failure(call, &why)).await;
        }
        let request: serde_json::Value = if call.payload.is_empty() {
            serde_json::json!({})
        } else {
            match serde_json::from_slice(&call.payload) {
                Ok(request) => request,
                Err(e) => {
                    return put(sink, ops::service_failure(call, &format!("not JSON: {e}"))).await;
                }
            }
        };
        let message = match service.message(&request) {
            Ok(Some(message)) => message,
            Ok(None) => return self.take_control(sink, call, &request).await,
            Err(why) => return put(sink, ops::service_failure(call, &why)).await,
        };
        self.tell_hub(message).await?;
        let answer = serde_json::json!({"ok": true, "message": "asked the lab; a refusal comes as a status"});
        put(sink, ops::service_response(call, &answer)).await
    }

    /// Asks for the operator's role, as the account in `request` at a lab
    /// with accounts.
    async fn take_control(
        &self,
        sink: &mut Sink,
        call: &ServiceCall,
        request: &serde_json::Value,
    ) -> Result<(), ()> {
        let credentials = Credentials {
            role: Role::Operator,
            user: request["user"].as_str(),
            password: request["password"].as_str(),
            token: None,
            session: None,
            purpose: Purpose::Session,
        };
        match self.gate.check(self.id, self.peer.ip(), credentials).await {
            Ok(admitted) if admitted.may_drive => {
                let hello = ToHub::Hello {
                    id: self.id,
                    admitted,
                    protocol: PROTOCOL_VERSION,
                    role: Role::Operator,
                    resume: None,
                };
                self.hub.send(hello).await.map_err(|_| ())?;
                let answer = serde_json::json!({"ok": true, "message": "asked for the operator's role: a status says whether it is yours"});
                put(sink, ops::service_response(call, &answer)).await
            }
            Ok(_) => {
                put(
                    sink,
                    ops::service_failure(call, "this account may watch, not drive"),
                )
                .await
            }
            Err(refused) => put(sink, ops::service_failure(call, &refused.why)).await,
        }
    }

    /// A text op: subscriptions and the client's own channels.
    async fn op(&self, sink: &mut Sink, client: &mut Client, op: &str) -> Result<(), ()> {
        let reply = match serde_json::from_str::<ClientOp>(op) {
            Ok(ClientOp::Subscribe { subscriptions }) => {
                let mut refused = Vec::new();
                for s in subscriptions {
                    let Some(&topic) = CHANNELS.get(s.channel_id as usize) else {
                        refused.push(format!("no channel {}", s.channel_id));
                        continue;
                    };
                    if client.holds(s.id) {
                        refused.push(format!("subscription id {} is in use", s.id));
                        continue;
                    }
                    if client.subscriptions() >= MAX_SUBSCRIPTIONS {
                        refused.push(format!(
                            "at most {MAX_SUBSCRIPTIONS} subscriptions a client"
                        ));
                        break;
                    }
                    let camera_before = client.watches_camera();
                    client.subscribed.entry(topic).or_default().push(s.id);
                    if !camera_before && client.watches_camera() {
                        self.feed.watch_camera(true);
                    }
                    for view in self.feed.latched(topic) {
                        send_within(&mut client.out, sink, s.id, &view).await?;
                    }
                }
                (!refused.is_empty()).then(|| status(StatusLevel::Warning, &refused.join("; ")))
            }
            Ok(ClientOp::Unsubscribe { subscription_ids }) => {
                let camera_before = client.watches_camera();
                let unknown: Vec<String> = subscription_ids
                    .iter()
                    .filter(|&&id| !client.holds(id))
                    .map(u32::to_string)
                    .collect();
                for ids in client.subscribed.values_mut() {
                    ids.retain(|id| !subscription_ids.contains(id));
                }
                if camera_before && !client.watches_camera() {
                    self.feed.watch_camera(false);
                }
                (!unknown.is_empty()).then(|| {
                    status(
                        StatusLevel::Warning,
                        &format!("no subscription {}", unknown.join(", ")),
                    )
                })
            }
            // Any topic may be advertised (a 3D panel advertises where its
            // clicks would go): only what is published on one but
            // `/cmd_vel` in json is refused, when it comes.
            Ok(ClientOp::Advertise { channels }) => {
                let mut refused = None;
                for channel in channels {
                    if client.advertised >= MAX_CLIENT_CHANNELS {
                        refused = Some(format!("at most {MAX_CLIENT_CHANNELS} channels a client"));
                        break;
                    }
                    client.advertised += 1;
                    if channel.topic == CMD_VEL && channel.encoding == "json" {
                        client.cmd_vel.insert(channel.id);
                    }
                }
                refused.map(|why| status(StatusLevel::Warning, &why))
            }
            Ok(ClientOp::Unadvertise { channel_ids }) => {
                for id in channel_ids {
                    client.cmd_vel.remove(&id);
                }
                None
            }
            Err(e) => Some(status(
                StatusLevel::Warning,
                &format!(
                    "this server takes subscribe, unsubscribe, advertise and unadvertise: {e}"
                ),
            )),
        };
        match reply {
            Some(reply) => put(sink, reply).await,
            None => Ok(()),
        }
    }
}

/// Ends the connection with a close frame saying why.
async fn close(sink: &mut Sink, ending: Ending) {
    let (code, reason) = match ending {
        Ending::Normal => (CloseCode::Normal, "goodbye"),
        Ending::Away => (CloseCode::Away, "the Host is stopping"),
    };
    let frame = CloseFrame {
        code,
        reason: reason.into(),
    };
    // After the client's close, ours is refused and the close that
    // tungstenite queued in answer goes out with the flush.
    let _ = put(sink, Message::Close(Some(frame))).await;
    let _ = tokio::time::timeout(socket::WRITE_TIMEOUT, futures_util::SinkExt::close(sink)).await;
}
