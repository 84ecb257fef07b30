//! Live in Foxglove and Lichtblick: the Foxglove WebSocket protocol on the
//! Host's own port, told apart from a Guest by its subprotocol. A Foxglove
//! client is an observer like any other (the same gate, the same places to
//! watch from, the same newest-only feedback and frames) that never
//! speaks: it is advertised the channels a run's recording has, in the
//! same schemas (`vl_record::Views` makes both), and gets those it subscribes
//! to. Read-only: it cannot publish, call services or set parameters.
//!
//! Written here rather than with Foxglove's SDK (crate `foxglove`): the
//! SDK runs a server of its own on its own listener, with its own TLS
//! (aws-lc-rs) and admission; here the lab's port, TLS, admission and
//! gate stay one, and the views are the recorder's own.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use serde::Deserialize;
use tokio::sync::broadcast;
use tokio_tungstenite::tungstenite::{Bytes, Message};
use vl_core::{ErrorCode, HostMessage, PROTOCOL_VERSION, Role, Wire};

use super::admission::Ticket;
use super::bucket::Bucket;
use super::hub::{ToConnection, ToHub};
use super::socket::{self, Sink, Socket};
use crate::accounts::gate::{Credentials, Gate, Purpose};
use crate::lab::Watching;
use vl_record::{Level, Topic, View, Views, now_ns};

/// The protocol's two names: Foxglove's SDK and foxglove_bridge 3.x ask
/// for the first only, older clients and Lichtblick before 2026 for the
/// second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Subprotocol {
    Sdk,
    Websocket,
}

impl Subprotocol {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Subprotocol::Sdk => "foxglove.sdk.v1",
            Subprotocol::Websocket => "foxglove.websocket.v1",
        }
    }

    /// The one to answer a client offering `offered` (a
    /// `Sec-WebSocket-Protocol` header) with, the current name first.
    pub(super) fn chosen(offered: &str) -> Option<Subprotocol> {
        let offers: Vec<&str> = offered.split(',').map(str::trim).collect();
        [Subprotocol::Sdk, Subprotocol::Websocket]
            .into_iter()
            .find(|s| offers.contains(&s.name()))
    }
}

/// The channels advertised, their ids their places here.
const CHANNELS: [Topic; 14] = [
    Topic::Camera,
    Topic::Annotations,
    Topic::Pose,
    Topic::Transform,
    Topic::Scene,
    Topic::Log,
    Topic::Feedback,
    Topic::State,
    Topic::Status,
    Topic::Lab,
    Topic::Definition,
    Topic::Forecast,
    Topic::Started,
    Topic::Summary,
];

/// Channels whose newest message a late subscriber gets at once: they
/// change seldom and say what the lab is.
const LATCHED: [Topic; 6] = [
    Topic::Scene,
    Topic::State,
    Topic::Status,
    Topic::Lab,
    Topic::Definition,
    Topic::Forecast,
];

/// Subscriptions one client may hold.
const MAX_SUBSCRIPTIONS: usize = 64;
/// The largest message a Foxglove client may send (a subscribe to every
/// channel is a few hundred bytes).
pub(super) const MAX_MESSAGE: usize = 64 << 10;
/// How often the Host pings a Foxglove client (WebSocket pings, which
/// every client answers by itself).
const PING_EVERY: Duration = Duration::from_secs(1);
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

/// Message data, server to client.
const MESSAGE_DATA: u8 = 0x01;

/// What a Foxglove client asks.
#[derive(Deserialize)]
#[serde(tag = "op", rename_all = "camelCase")]
enum ClientOp {
    Subscribe {
        subscriptions: Vec<Subscription>,
    },
    #[serde(rename_all = "camelCase")]
    Unsubscribe {
        subscription_ids: Vec<u32>,
    },
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Subscription {
    id: u32,
    channel_id: u32,
}

fn text(value: serde_json::Value) -> Message {
    Message::text(value.to_string())
}

/// A status message to the client: 0 info, 1 warning, 2 error.
fn status(level: u8, message: &str) -> Message {
    text(serde_json::json!({"op": "status", "level": level, "message": message}))
}

fn server_info(connection: u64) -> Message {
    text(serde_json::json!({
        "op": "serverInfo",
        "name": format!("vl host {}", env!("CARGO_PKG_VERSION")),
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": {},
        "sessionId": connection.to_string(),
    }))
}

fn advertise() -> Message {
    let channels: Vec<serde_json::Value> = CHANNELS
        .iter()
        .enumerate()
        .map(|(id, topic)| {
            let schema = topic.schema();
            serde_json::json!({
                "id": id,
                "topic": topic.name(),
                "encoding": "json",
                "schemaName": schema.name,
                "schema": schema.body.to_string(),
                "schemaEncoding": "jsonschema",
            })
        })
        .collect();
    text(serde_json::json!({"op": "advertise", "channels": channels}))
}

/// One client's subscriptions and what it has been told.
struct Subscriptions {
    /// Subscription ids by channel.
    subscribed: HashMap<Topic, Vec<u32>>,
    views: Views,
    latest: HashMap<Topic, View>,
    /// What it may still be sent now.
    out: Bucket,
}

impl Subscriptions {
    fn wants(&self, topic: Topic) -> bool {
        self.subscribed
            .get(&topic)
            .is_some_and(|ids| !ids.is_empty())
    }

    fn count(&self) -> usize {
        self.subscribed.values().map(Vec::len).sum()
    }

    /// Sends `views` to whoever subscribed to their channels, keeping the
    /// latched ones for later subscribers.
    async fn send(&mut self, sink: &mut Sink, views: Vec<View>) -> Result<(), ()> {
        for view in views {
            if let Some(ids) = self.subscribed.get(&view.topic) {
                for &id in ids {
                    put_data(&mut self.out, sink, id, &view).await?;
                }
            }
            if LATCHED.contains(&view.topic) {
                self.latest.insert(view.topic, view);
            }
        }
        Ok(())
    }

    /// Takes what the client sent: only subscriptions are taken; a
    /// close ends the connection (`Err`).
    async fn heard(&mut self, sink: &mut Sink, message: Message) -> Result<(), ()> {
        match message {
            Message::Text(op) => self.take(sink, op.as_str()).await,
            Message::Binary(_) => {
                put(
                    sink,
                    status(1, "this server is read-only: nothing may be published"),
                )
                .await
            }
            Message::Close(_) => Err(()),
            _ => Ok(()),
        }
    }

    /// Passes on what the hub told every client, as its views.
    async fn hub_said(&mut self, sink: &mut Sink, message: &Message) -> Result<(), ()> {
        let Message::Text(json) = message else {
            return Ok(());
        };
        match HostMessage::decode(json.as_str()) {
            Ok(message) => {
                let views = self.views.sent(now_ns(), &message);
                self.send(sink, views).await
            }
            Err(_) => Ok(()),
        }
    }

    /// Takes a client's op; what to tell it, if anything.
    async fn take(&mut self, sink: &mut Sink, op: &str) -> Result<(), ()> {
        let reply = match serde_json::from_str::<ClientOp>(op) {
            Ok(ClientOp::Subscribe { subscriptions }) => {
                let mut refused = None;
                for s in subscriptions {
                    let Some(&topic) = CHANNELS.get(s.channel_id as usize) else {
                        refused = Some(format!("no channel {}", s.channel_id));
                        continue;
                    };
                    if self.count() >= MAX_SUBSCRIPTIONS {
                        refused = Some(format!(
                            "at most {MAX_SUBSCRIPTIONS} subscriptions a client"
                        ));
                        break;
                    }
                    self.subscribed.entry(topic).or_default().push(s.id);
                    if let Some(view) = self.latest.get(&topic) {
                        put_data(&mut self.out, sink, s.id, view).await?;
                    }
                }
                refused.map(|why| status(1, &why))
            }
            Ok(ClientOp::Unsubscribe { subscription_ids }) => {
                for ids in self.subscribed.values_mut() {
                    ids.retain(|id| !subscription_ids.contains(id));
                }
                None
            }
            Err(e) => Some(status(
                1,
                &format!("this server is read-only and takes subscribe and unsubscribe only: {e}"),
            )),
        };
        match reply {
            Some(reply) => put(sink, reply).await,
            None => Ok(()),
        }
    }
}

/// Sends `view` on subscription `id`, within the client's budget `out`;
/// past it, the message is not sent.
async fn put_data(out: &mut Bucket, sink: &mut Sink, id: u32, view: &View) -> Result<(), ()> {
    let message = data(id, view);
    let bytes = message.len() as f64;
    if !out.take(bytes).is_zero() {
        out.refund(bytes);
        return Ok(());
    }
    put(sink, message).await
}

/// Message data: opcode, subscription id, log time, payload.
fn data(subscription: u32, view: &View) -> Message {
    let mut bytes = Vec::with_capacity(13 + view.data.len());
    bytes.push(MESSAGE_DATA);
    bytes.extend_from_slice(&subscription.to_le_bytes());
    bytes.extend_from_slice(&view.ns.to_le_bytes());
    bytes.extend_from_slice(&view.data);
    Message::Binary(Bytes::from(bytes))
}

/// Writes `message` in time, or the client is let go (`Err`).
async fn put(sink: &mut Sink, message: Message) -> Result<(), ()> {
    socket::write(sink, message).await.map_err(|_| ())
}

/// A Foxglove client's connection, and what it takes from the lab.
pub(super) struct Watcher {
    pub id: u64,
    pub hub: tokio::sync::mpsc::Sender<ToHub>,
    pub feedback: tokio::sync::watch::Receiver<Option<HostMessage>>,
    pub frames: tokio::sync::watch::Receiver<Option<Bytes>>,
    pub watchers: std::sync::Arc<std::sync::atomic::AtomicUsize>,
    pub gate: std::sync::Arc<Gate>,
    pub peer: std::net::SocketAddr,
    pub ticket: Ticket,
    pub ping_timeout: Duration,
    pub log: broadcast::Sender<(Level, String)>,
    pub since_ns: u64,
}

impl Watcher {
    /// Serves a Foxglove client until it leaves or cannot be served.
    pub(super) async fn serve(mut self, socket: Socket) {
        let (mut sink, mut source) = socket.split();
        let anyone = Credentials {
            role: Role::Observer,
            user: None,
            password: None,
            token: None,
            purpose: Purpose::Session,
        };
        let admitted = match self.gate.check(self.id, self.peer.ip(), anyone).await {
            Ok(admitted) if self.ticket.seat(admitted.may_drive) => admitted,
            Ok(_) => {
                let why = "the lab is full: every place to watch from is taken";
                let _ = put(&mut sink, status(2, why)).await;
                return;
            }
            Err(refused) => {
                let _ = put(&mut sink, status(2, &refused.why)).await;
                return;
            }
        };
        let (to_me, mut inbox) = tokio::sync::mpsc::channel(super::hub::OUTBOX);
        if self.hub.send(ToHub::Join(self.id, to_me)).await.is_err() {
            return;
        }
        let hello = ToHub::Hello {
            id: self.id,
            admitted,
            protocol: PROTOCOL_VERSION,
            role: Role::Observer,
            resume: None,
        };
        if self.hub.send(hello).await.is_ok() {
            self.watch(&mut sink, &mut source, &mut inbox).await;
        }
        let _ = self.hub.send(ToHub::Leave(self.id, true)).await;
        let _ = put(&mut sink, Message::Close(None)).await;
    }

    async fn watch(
        &mut self,
        sink: &mut Sink,
        source: &mut futures_util::stream::SplitStream<Socket>,
        inbox: &mut tokio::sync::mpsc::Receiver<ToConnection>,
    ) {
        for opening in [server_info(self.id), advertise()] {
            if put(sink, opening).await.is_err() {
                return;
            }
        }
        let mut log = self.log.subscribe();
        let mut watcher = Subscriptions {
            subscribed: HashMap::new(),
            views: Views::new(self.since_ns, None, Default::default()),
            latest: HashMap::new(),
            out: Bucket::new(BYTES_OUT_PER_S, BYTES_OUT_BURST),
        };
        let mut ops = Bucket::new(OPS_PER_S, OPS_BURST);
        let mut paused_until: Option<tokio::time::Instant> = None;
        let mut watching = None;
        let mut ping = tokio::time::interval(PING_EVERY);
        let mut heard = Instant::now();
        let mut evicted = self.ticket.evicted.clone();
        loop {
            let sent = tokio::select! {
                () = async { tokio::time::sleep_until(paused_until.unwrap_or_else(tokio::time::Instant::now)).await }, if paused_until.is_some() => {
                    paused_until = None;
                    Ok(())
                }
                incoming = source.next(), if paused_until.is_none() => match incoming {
                    Some(Ok(message)) => {
                        heard = Instant::now();
                        // Over its rate, the client is not read for a while:
                        // its own socket holds it back.
                        let wait = ops.take(1.0);
                        if !wait.is_zero() {
                            paused_until = Some(tokio::time::Instant::now() + wait);
                        }
                        watcher.heard(sink, message).await
                    }
                    Some(Err(_)) | None => return,
                },
                out = inbox.recv() => match out {
                    Some(ToConnection::Send(message)) => watcher.hub_said(sink, &message).await,
                    Some(ToConnection::End(..)) => return,
                    Some(ToConnection::Subscribe) => {
                        watching.get_or_insert_with(|| Watching::new(&self.watchers));
                        self.ticket.welcomed();
                        self.feedback.mark_changed();
                        self.frames.mark_changed();
                        Ok(())
                    }
                    None => {
                        let _ = put(sink, status(2, ErrorCode::SlowReader.to_string().as_str())).await;
                        return;
                    }
                },
                Ok(()) = self.feedback.changed(), if watching.is_some() => {
                    let latest = self.feedback.borrow_and_update().clone();
                    match latest {
                        Some(message) => {
                            let views = watcher.views.sent(now_ns(), &message);
                            watcher.send(sink, views).await
                        }
                        None => Ok(()),
                    }
                }
                Ok(()) = self.frames.changed(), if watching.is_some() => {
                    let latest = self.frames.borrow_and_update().clone();
                    match latest {
                        // Only a subscriber's frame is made into base64 JSON.
                        Some(frame) if watcher.wants(Topic::Camera) || watcher.wants(Topic::Annotations) => {
                            let views = watcher.views.frame(&frame);
                            watcher.send(sink, views).await
                        }
                        _ => Ok(()),
                    }
                }
                line = log.recv() => match line {
                    Ok((level, line)) => watcher.send(sink, vec![View::log(now_ns(), level, &line)]).await,
                    Err(broadcast::error::RecvError::Lagged(skipped)) => {
                        let line = format!("{skipped} lines of the Host's log skipped: this client fell behind");
                        watcher.send(sink, vec![View::log(now_ns(), Level::Warning, &line)]).await
                    }
                    Err(broadcast::error::RecvError::Closed) => return,
                },
                Ok(()) = evicted.changed() => {
                    if *evicted.borrow() {
                        return;
                    }
                    Ok(())
                }
                () = self.hub.closed() => return,
                _ = ping.tick() => {
                    if heard.elapsed() > self.ping_timeout {
                        return;
                    }
                    put(sink, Message::Ping(Bytes::new())).await
                }
            };
            if sent.is_err() {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_current_name_is_chosen_first_and_others_are_not_foxglove() {
        assert_eq!(
            Subprotocol::chosen("foxglove.websocket.v1, foxglove.sdk.v1"),
            Some(Subprotocol::Sdk)
        );
        assert_eq!(
            Subprotocol::chosen("foxglove.websocket.v1"),
            Some(Subprotocol::Websocket)
        );
        assert_eq!(Subprotocol::chosen("vl.v1"), None);
        assert_eq!(Subprotocol::chosen(""), None);
    }

    #[test]
    fn every_channel_is_advertised_once_with_its_schema() {
        let Message::Text(json) = advertise() else {
            panic!("advertise is text")
        };
        let value: serde_json::Value = serde_json::from_str(json.as_str()).unwrap();
        let channels = value["channels"].as_array().unwrap();
        assert_eq!(channels.len(), CHANNELS.len());
        for (id, channel) in channels.iter().enumerate() {
            assert_eq!(channel["id"], id);
            let schema: serde_json::Value =
                serde_json::from_str(channel["schema"].as_str().unwrap()).unwrap();
            assert!(schema.is_object(), "{channel}");
        }
    }

    #[test]
    fn message_data_is_opcode_subscription_time_payload() {
        let view = View {
            topic: Topic::Pose,
            ns: 0x0102_0304_0506_0708,
            data: b"{}".to_vec(),
        };
        let Message::Binary(bytes) = data(7, &view) else {
            panic!("message data is binary")
        };
        assert_eq!(bytes[0], 1);
        assert_eq!(&bytes[1..5], &7u32.to_le_bytes());
        assert_eq!(&bytes[5..13], &view.ns.to_le_bytes());
        assert_eq!(&bytes[13..], b"{}");
    }
}
