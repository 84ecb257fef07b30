//! One connection's task: the WebSocket handshake, reading and decoding
//! what the client sends (within size and rate limits, off the hub), and
//! writing what the hub, the lab's feedback and the camera have for it —
//! each stage with a timeout.

use std::sync::Arc;
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use tokio::net::TcpStream;
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::{self, Bytes, Message};
use tracing::debug;
use vl_core::{
    ErrorCode, GuestMessage, HostMessage, MAX_TEXT_BYTES, PartHeader, RecordingName, Wire,
};

use super::admission::Ticket;
use super::events::LiveEvent;
use super::extension::{Extension, SocketClient};
use super::http::{self, Opening};
use super::hub::{ToConnection, ToHub};
use super::socket::{self, Sink, Socket, Unwritten};
use super::{HostConfig, LabHandle};
use crate::accounts::gate::{Credentials, Identity, Purpose};
use crate::lab::Watching;
use tokio_tungstenite::tungstenite::handshake::server::{Request, Response};

use super::bucket::Bucket;
use super::origin::AllowedOrigins;
use vl_core::Io;
use vl_record::{RecordError, Recordable};

/// The WebSocket handshake must be done within this.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// How often the Host pings: to measure the round trip and hear the client.
const PING_EVERY: Duration = Duration::from_secs(1);
/// Bytes of messages waiting to be written to one client, at most.
const WRITE_BUFFER: usize = 4 << 20;
/// Messages a client may send per second, and in a burst.
const RATE_PER_S: f64 = 200.0;
const BURST: f64 = 400.0;
/// Bytes a client may send per second, and in a burst: a definition at its
/// largest fits in the burst.
const BYTES_PER_S: f64 = 1024.0 * 1024.0;
const BYTES_BURST: f64 = 2.0 * 1024.0 * 1024.0;
/// Bytes of answers (recordings' parts, listings) a client may draw a
/// second, and in a burst: a download at a good link's speed. Past it the
/// client is not read until it is within it again: asking faster gets
/// nothing faster.
const ANSWER_BYTES_PER_S: f64 = 8.0 * 1024.0 * 1024.0;
const ANSWER_BYTES_BURST: f64 = 16.0 * 1024.0 * 1024.0;
/// Messages refused before hello, in all, before the client is cut off.
const MAX_BEFORE_HELLO: u32 = 16;
/// How long a client refused before hello is held before it is closed.
const REFUSED_HOLD: Duration = Duration::from_secs(1);
/// The largest message taken before hello: a hello is a few dozen bytes.
const MAX_BEFORE_HELLO_BYTES: usize = 4096;

/// A connection's task and what it shares.
pub(crate) struct ConnectionTask {
    pub(crate) id: u64,
    /// The lab: its hub, the feedback and frames (counted among the
    /// frames' watchers once welcomed), the gate each hello passes, the
    /// recorder and the live views each round trip measured goes to.
    pub(crate) lab: LabHandle,
    pub(crate) config: Arc<HostConfig>,
    pub(crate) peer: std::net::SocketAddr,
    pub(crate) ticket: Ticket,
    /// Who the gate let in (for the recordings they may see).
    pub(crate) identity: Option<Identity>,
}

/// Who a connection's WebSocket is for.
enum Client {
    /// With the path it opened (`/cells/NAME` asks a gateway for a cell).
    Guest(Socket, Option<String>),
    /// A client of a protocol an extension serves.
    Extension(Socket, Arc<dyn Extension>),
}

/// How a connection ends.
#[derive(Debug)]
enum End {
    /// Quietly: the socket ended without a word (a dropped link), or the
    /// Host is stopping.
    Closed,
    /// The client said bye or closed the WebSocket: it means to leave.
    Left,
    /// With an `error` to the client saying why, then a close.
    Refused(ErrorCode, String),
    /// The socket failed.
    Failed(tungstenite::Error),
}

/// A round trip longer than this, ms, is no true one (the Host would have
/// let the client go first).
const PING_TIMEOUT_MS: f64 = 60_000.0;

/// How long a closing connection waits for the client's own close.
const CLOSE_WAIT: Duration = Duration::from_millis(500);

/// Writes `message`, within the write timeout.
async fn put(sink: &mut Sink, message: Message) -> Result<(), End> {
    socket::write(sink, message).await.map_err(|e| match e {
        // It cannot be told why: it is not reading.
        Unwritten::TimedOut => End::Closed,
        Unwritten::Failed(e) => End::Failed(e),
    })
}

fn text_of(message: &HostMessage) -> Message {
    Message::text(message.encode())
}

/// What reading a client's messages keeps between them. A client faster
/// than its rate is not read until it is within it again: its own socket
/// then holds it back, at no cost to the Host. Commands are the exception:
/// they are values, the newest wins, so one over the rate waits (in place
/// of any before it) for the rate to allow it, and reading goes on: an
/// emergency stop behind a flood of commands is never held back by them.
struct Reading {
    clock: Instant,
    /// When the client was last heard from.
    heard: Instant,
    welcomed: bool,
    messages: Bucket,
    bytes: Bucket,
    /// What the connection's own answers may still send.
    answers: Bucket,
    /// Reading waits until then.
    paused_until: Option<tokio::time::Instant>,
    held_command: Option<(tokio::time::Instant, GuestMessage)>,
    before_hello: u32,
}

/// Takes the connection's TLS handshake, if any, and its opening: a
/// WebSocket handshake (a Guest's or a Foxglove client's), or a page
/// request answered here (none).
async fn handshake(
    stream: TcpStream,
    tls: Option<Arc<rustls::ServerConfig>>,
    ws_config: WebSocketConfig,
    asking: http::Asking,
    origins: &AllowedOrigins,
) -> Result<Option<Client>, tungstenite::Error> {
    let stream: Box<dyn Io> = match tls {
        Some(tls) => {
            // A TLS handshake opens with a record of type 22; a letter is
            // plain HTTP (a browser given http://), sent on to https://.
            let mut first = [0u8; 1];
            if stream.peek(&mut first).await? == 1 && first[0].is_ascii_alphabetic() {
                http::to_https(Box::new(stream)).await?;
                return Ok(None);
            }
            Box::new(tokio_rustls::TlsAcceptor::from(tls).accept(stream).await?)
        }
        None => Box::new(stream),
    };
    match http::opening(stream, &asking.extensions).await? {
        Opening::Guest(stream) => {
            let mut path = None;
            // tungstenite's callback type fixes the error's size.
            #[allow(clippy::result_large_err)]
            let answer = |request: &Request, response: Response| {
                from_allowed_origin(request, origins)?;
                path = Some(request.uri().path().to_owned());
                Ok(response)
            };
            let socket =
                tokio_tungstenite::accept_hdr_async_with_config(stream, answer, Some(ws_config))
                    .await?;
            Ok(Some(Client::Guest(socket, path)))
        }
        Opening::Extension(stream, extension, protocol) => {
            // tungstenite's callback type fixes the error's size.
            #[allow(clippy::result_large_err)]
            let answer = |request: &Request, mut response: Response| {
                from_allowed_origin(request, origins)?;
                response.headers_mut().insert(
                    "sec-websocket-protocol",
                    tungstenite::http::HeaderValue::from_static(protocol.name),
                );
                Ok(response)
            };
            let config = ws_config
                .max_message_size(Some(protocol.max_message))
                .max_frame_size(Some(protocol.max_message));
            tokio_tungstenite::accept_hdr_async_with_config(stream, answer, Some(config))
                .await
                .map(|socket| Some(Client::Extension(socket, extension)))
        }
        Opening::Page(stream) => {
            http::answer(stream, asking).await?;
            Ok(None)
        }
    }
}

/// Refuses (403, saying why) a WebSocket a web page from an origin the
/// Host does not allow opens.
#[allow(clippy::result_large_err)]
fn from_allowed_origin(
    request: &Request,
    origins: &AllowedOrigins,
) -> Result<(), tungstenite::handshake::server::ErrorResponse> {
    let header = |name: &str| request.headers().get(name).and_then(|v| v.to_str().ok());
    origins
        .admit(header("origin"), header("host"))
        .map_err(|why| {
            debug!("{why}");
            let mut refused = tungstenite::handshake::server::ErrorResponse::new(Some(why));
            *refused.status_mut() = tungstenite::http::StatusCode::FORBIDDEN;
            refused
        })
}

impl ConnectionTask {
    pub(crate) async fn run(mut self, stream: TcpStream) -> Result<(), tungstenite::Error> {
        let _ = stream.set_nodelay(true);
        // Guests send only text: nothing larger than a text message may come.
        let ws_config = WebSocketConfig::default()
            .max_message_size(Some(MAX_TEXT_BYTES))
            .max_frame_size(Some(MAX_TEXT_BYTES))
            .max_write_buffer_size(WRITE_BUFFER);
        let tls = self.config.tls.as_ref().map(|tls| tls.config.clone());
        let asking = http::Asking {
            connection: self.id,
            address: self.peer.ip(),
            gate: self.lab.gate.clone(),
            hub: self.lab.hub.clone(),
            extensions: self.config.extensions.clone(),
        };
        let origins = self.config.allow_origins.clone();
        let spare = super::busy::spare(&stream, tls.is_some());
        let handshake = handshake(stream, tls, ws_config, asking, &origins);
        let mut evicted = self.ticket.evicted.clone();
        let ws = tokio::select! {
            ws = tokio::time::timeout(HANDSHAKE_TIMEOUT, handshake) => match ws {
                Ok(Ok(Some(client))) => client,
                // A page was asked for, and answered.
                Ok(Ok(None)) => return Ok(()),
                Ok(Err(e)) => return Err(e),
                Err(_) => {
                    debug!(connection = self.id, "no handshake within {HANDSHAKE_TIMEOUT:?}");
                    return Ok(());
                }
            },
            // A newer connection needed the slot of one still shaking hands.
            _ = evicted.wait_for(|out| *out) => {
                super::busy::refuse_spare(spare);
                return Ok(());
            }
        };
        drop(spare);
        self.ticket.upgraded();
        let (ws, path) = match ws {
            Client::Guest(ws, path) => (ws, path),
            Client::Extension(ws, extension) => {
                let client = SocketClient {
                    id: self.id,
                    peer: self.peer,
                    ticket: self.ticket,
                    lab: self.lab,
                    ping_timeout: self.config.ping_timeout,
                };
                extension.serve_socket(ws, client).await;
                return Ok(());
            }
        };
        let (mut sink, mut source) = ws.split();
        let (to_me, mut inbox) = mpsc::channel(super::hub::OUTBOX);
        if self
            .lab
            .hub
            .send(ToHub::Join(self.id, to_me, path))
            .await
            .is_err()
        {
            return Ok(());
        }
        let end = self.serve(&mut sink, &mut source, &mut inbox).await;
        let left = matches!(end, End::Left);
        let _ = self.lab.hub.send(ToHub::Leave(self.id, left)).await;
        match end {
            End::Closed | End::Left => {}
            End::Refused(code, why) => {
                debug!(connection = self.id, %code, "closing: {why}");
                let _ = put(&mut sink, text_of(&HostMessage::error(code, why))).await;
                // A client refused before it was welcomed is held, unread,
                // for a while: one that reconnects at once to try again
                // would otherwise cost a handshake each time.
                if !*self.ticket.evicted.borrow() && !self.ticket.is_welcomed() {
                    let mut evicted = self.ticket.evicted.clone();
                    let _ = tokio::time::timeout(REFUSED_HOLD, evicted.wait_for(|out| *out)).await;
                }
            }
            End::Failed(e) => return Err(e),
        }
        let _ = put(&mut sink, Message::Close(None)).await;
        // Read on a moment, until the client closes too: a socket dropped
        // with the client's pongs still unread is reset, and the reset can
        // take the error just sent with it.
        let _ = tokio::time::timeout(CLOSE_WAIT, async {
            while let Some(Ok(message)) = source.next().await {
                if message.is_close() {
                    break;
                }
            }
        })
        .await;
        Ok(())
    }

    async fn serve(
        &mut self,
        sink: &mut Sink,
        source: &mut futures_util::stream::SplitStream<Socket>,
        inbox: &mut mpsc::Receiver<ToConnection>,
    ) -> End {
        let hello_by = tokio::time::Instant::now() + self.config.hello_timeout;
        let mut ping = tokio::time::interval(PING_EVERY);
        let mut watching = None;
        let mut r = Reading {
            clock: Instant::now(),
            heard: Instant::now(),
            welcomed: false,
            messages: Bucket::new(RATE_PER_S, BURST),
            bytes: Bucket::new(BYTES_PER_S, BYTES_BURST),
            answers: Bucket::new(ANSWER_BYTES_PER_S, ANSWER_BYTES_BURST),
            paused_until: None,
            held_command: None,
            before_hello: 0,
        };
        let mut evicted = self.ticket.evicted.clone();
        loop {
            tokio::select! {
                () = async { tokio::time::sleep_until(r.paused_until.unwrap_or_else(tokio::time::Instant::now)).await }, if r.paused_until.is_some() => {
                    r.paused_until = None;
                }
                () = async { tokio::time::sleep_until(r.held_command.as_ref().map_or_else(tokio::time::Instant::now, |(at, _)| *at)).await }, if r.held_command.is_some() => {
                    if let Some((_, command)) = r.held_command.take()
                        && self.to_hub(command).await.is_err()
                    {
                        return End::Closed;
                    }
                }
                incoming = source.next(), if r.paused_until.is_none() => {
                    if let Err(end) = self.read(incoming, sink, &mut r).await {
                        return end;
                    }
                }
                out = inbox.recv() => match out {
                    Some(ToConnection::Send(message)) => {
                        if let Err(end) = put(sink, message).await {
                            return end;
                        }
                    }
                    Some(ToConnection::End(code, why)) => return End::Refused(code, why),
                    Some(ToConnection::Watch(streams)) => {
                        self.lab.feedback = streams.feedback;
                        self.lab.frames = streams.frames;
                        self.subscribed(&mut r, &mut watching);
                    }
                    Some(ToConnection::Subscribe) => self.subscribed(&mut r, &mut watching),
                    // The hub let go of this client: it could not keep up.
                    None => {
                        return End::Refused(ErrorCode::SlowReader, "messages for you piled up unread".into());
                    }
                },
                Ok(()) = self.lab.feedback.changed(), if r.welcomed => {
                    let latest = self.lab.feedback.borrow_and_update().clone();
                    if let Some(message) = latest
                        && let Err(end) = put(sink, text_of(&message)).await
                    {
                        return end;
                    }
                }
                Ok(()) = self.lab.frames.changed(), if r.welcomed => {
                    let latest = self.lab.frames.borrow_and_update().clone();
                    if let Some(frame) = latest
                        && let Err(end) = put(sink, Message::Binary(frame)).await
                    {
                        return end;
                    }
                }
                () = tokio::time::sleep_until(hello_by), if !r.welcomed => {
                    let why = format!("no hello within {} s", self.config.hello_timeout.as_secs_f64());
                    return End::Refused(ErrorCode::Timeout, why);
                }
                Ok(()) = evicted.changed() => {
                    if *evicted.borrow() {
                        return End::Refused(ErrorCode::Timeout, "pushed out by a newer connection: say hello sooner".into());
                    }
                }
                () = self.lab.hub.closed() => {
                    let _ = put(sink, text_of(&HostMessage::Bye)).await;
                    return End::Closed;
                }
                _ = ping.tick() => {
                    if r.heard.elapsed() > self.config.ping_timeout {
                        let why = format!("nothing heard for {} s", self.config.ping_timeout.as_secs_f64());
                        return End::Refused(ErrorCode::Timeout, why);
                    }
                    let t = r.clock.elapsed().as_secs_f64() * 1e3;
                    if let Err(end) = put(sink, text_of(&HostMessage::Ping { t })).await {
                        return end;
                    }
                }
            }
        }
    }

    /// Welcomed: the newest feedback and frame are for this client now.
    fn subscribed(&mut self, r: &mut Reading, watching: &mut Option<Watching>) {
        r.welcomed = true;
        watching.get_or_insert_with(|| Watching::new(&self.lab.watchers));
        self.ticket.welcomed();
        self.lab.feedback.mark_changed();
        self.lab.frames.mark_changed();
    }

    /// Takes in what the client sent, within its rates.
    async fn read(
        &mut self,
        incoming: Option<Result<Message, tungstenite::Error>>,
        sink: &mut Sink,
        r: &mut Reading,
    ) -> Result<(), End> {
        let message = match incoming {
            None => return Err(End::Closed),
            Some(Ok(Message::Close(_))) => return Err(End::Left),
            Some(Err(tungstenite::Error::Capacity(e))) => {
                // The rest of that message cannot be skipped.
                return Err(End::Refused(
                    ErrorCode::TooLarge,
                    format!("message too large: {e}"),
                ));
            }
            Some(Err(e)) => return Err(End::Failed(e)),
            Some(Ok(message)) => message,
        };
        r.heard = Instant::now();
        let over_rate = r.messages.take(1.0);
        let over_bytes = r.bytes.take(message.len() as f64);
        if !over_bytes.is_zero() {
            r.paused_until = Some(tokio::time::Instant::now() + over_bytes);
        }
        if !r.welcomed && message.len() > MAX_BEFORE_HELLO_BYTES {
            return Err(End::Refused(
                ErrorCode::TooLarge,
                "a message this large before hello".into(),
            ));
        }
        let text = match message {
            Message::Text(text) => text,
            Message::Binary(_) => {
                let reply = HostMessage::error(
                    ErrorCode::BadMessage,
                    "binary messages flow only from Host to Guest",
                );
                return put(sink, text_of(&reply)).await;
            }
            // WebSocket pings are answered by tungstenite.
            _ => return Ok(()),
        };
        match self.route(text.as_str(), r, over_rate).await? {
            Some(reply) => {
                // Answered here, over its budget for answers (a part, a
                // listing), the client is not read for a while.
                let over = r.answers.take(reply.len() as f64);
                if !over.is_zero() {
                    let until = tokio::time::Instant::now() + over;
                    r.paused_until = Some(r.paused_until.map_or(until, |p| p.max(until)));
                }
                put(sink, reply).await
            }
            None => Ok(()),
        }
    }

    /// Passes `message` to the hub; the connection ends with the hub.
    async fn to_hub(&self, message: GuestMessage) -> Result<(), End> {
        self.lab
            .hub
            .send(ToHub::Message(self.id, message))
            .await
            .map_err(|_| End::Closed)
    }

    /// A pong's round trip, into the run's record: only a welcomed
    /// client's, and only a true one — a stranger's socket, or a pong
    /// echoing a time never sent, writes nothing into the experiment's data.
    fn round_trip(&self, r: &Reading, t: f64) {
        let rtt_ms = r.clock.elapsed().as_secs_f64() * 1e3 - t;
        debug!(connection = self.id, rtt_ms, "round trip");
        if r.welcomed && (0.0..=PING_TIMEOUT_MS).contains(&rtt_ms) {
            self.lab.record.send(Recordable::RoundTrip {
                connection: self.id,
                ms: rtt_ms,
            });
            let connection = self.id;
            self.lab.live.tell(|| LiveEvent::RoundTrip {
                connection,
                ms: rtt_ms,
            });
        }
    }

    /// Passes a text message on to the hub, or answers it here (pings,
    /// refusals before hello); over the rate, a command waits in place of
    /// any before it and anything else pauses reading.
    async fn route(
        &mut self,
        text: &str,
        r: &mut Reading,
        over_rate: Duration,
    ) -> Result<Option<Message>, End> {
        let reply = match GuestMessage::decode(text) {
            Ok(GuestMessage::Ping { t }) => Some(HostMessage::Pong { t }),
            Ok(GuestMessage::Pong { t }) => {
                self.round_trip(r, t);
                None
            }
            Ok(GuestMessage::Bye) => return Err(End::Left),
            Ok(GuestMessage::Hello {
                protocol,
                role,
                token,
                resume,
                user,
                password,
                session,
            }) => {
                self.ticket.greeted();
                let hello = Credentials {
                    role,
                    user: user.as_deref(),
                    password: password.as_ref().map(|p| p.0.as_str()),
                    token: token.as_deref(),
                    session: session.as_ref().map(|s| s.0.as_str()),
                    purpose: Purpose::Session,
                };
                match self.lab.gate.check(self.id, self.peer.ip(), hello).await {
                    Ok(admitted) if !self.ticket.seat(admitted.may_drive) => {
                        return Err(End::Refused(
                            ErrorCode::LabFull,
                            "the lab is full: every place to watch from is taken (the rest are kept for those who may drive); try again later".into(),
                        ));
                    }
                    Ok(admitted) => {
                        self.identity = Some(admitted.identity.clone());
                        let hello = ToHub::Hello {
                            id: self.id,
                            admitted,
                            protocol,
                            role,
                            resume,
                        };
                        self.lab.hub.send(hello).await.map_err(|_| End::Closed)?;
                        None
                    }
                    Err(refused) => {
                        r.before_hello += 1;
                        if r.before_hello >= MAX_BEFORE_HELLO {
                            return Err(End::Refused(refused.code, refused.why));
                        }
                        Some(HostMessage::error(refused.code, refused.why))
                    }
                }
            }
            // Before hello nothing else reaches the hub.
            Ok(_) if !r.welcomed => {
                r.before_hello += 1;
                if r.before_hello >= MAX_BEFORE_HELLO {
                    return Err(End::Refused(
                        ErrorCode::HelloFirst,
                        "nothing but hello before hello".into(),
                    ));
                }
                Some(HostMessage::error(
                    ErrorCode::HelloFirst,
                    "send hello first",
                ))
            }
            Ok(GuestMessage::Recordings) => Some(self.recordings().await),
            Ok(GuestMessage::Download { name, offset }) => {
                return Ok(Some(self.download(name, offset).await));
            }
            Ok(message @ GuestMessage::Command { .. }) if !over_rate.is_zero() => {
                // The one it replaces is never forwarded: it costs nothing.
                let wait = match r.held_command.take() {
                    Some((at, _)) => {
                        r.messages.refund(1.0);
                        at.saturating_duration_since(tokio::time::Instant::now())
                    }
                    None => over_rate,
                };
                r.held_command = Some((tokio::time::Instant::now() + wait, message));
                None
            }
            Ok(message) => {
                if matches!(message, GuestMessage::Command { .. }) {
                    // A newer command than the one held: that one is stale.
                    r.held_command = None;
                } else if !over_rate.is_zero() && !matches!(message, GuestMessage::EmergencyStop) {
                    let until = tokio::time::Instant::now() + over_rate;
                    r.paused_until = Some(r.paused_until.map_or(until, |p| p.max(until)));
                }
                self.to_hub(message).await?;
                None
            }
            Err(e) => Some(HostMessage::error(e.code(), e.to_string())),
        };
        Ok(reply.map(|reply| text_of(&reply)))
    }

    /// Who this client is to the recordings, and whether they see all.
    fn owner(&self) -> Option<(vl_record::Catalogue, vl_record::Owner, bool)> {
        let catalogue = self.config.recordings.clone()?;
        let identity = self.identity.as_ref()?;
        let admin = identity.is_admin();
        let owner = catalogue.owner(identity.name(), self.id);
        Some((catalogue, owner, admin))
    }

    /// The recorded runs this client may see.
    async fn recordings(&self) -> HostMessage {
        let Some((catalogue, owner, admin)) = self.owner() else {
            return HostMessage::Recordings { runs: Vec::new() };
        };
        let runs = tokio::task::spawn_blocking(move || catalogue.visible(&owner, admin)).await;
        HostMessage::Recordings {
            runs: runs.unwrap_or_default(),
        }
    }

    /// The part of recording `name` from `offset`, or why not.
    async fn download(&self, name: RecordingName, offset: u64) -> Message {
        let Some((catalogue, owner, admin)) = self.owner() else {
            let why = "this Host records nothing";
            return text_of(&HostMessage::error(ErrorCode::UnknownRecording, why));
        };
        let wanted = name.clone();
        let part =
            tokio::task::spawn_blocking(move || catalogue.part(&wanted, offset, &owner, admin))
                .await
                .unwrap_or_else(|e| {
                    Err(RecordError::Io(
                        name.as_str().into(),
                        std::io::Error::other(e),
                    ))
                });
        match part {
            Ok((total, bytes)) => {
                let header = PartHeader {
                    name,
                    offset,
                    total,
                };
                Message::Binary(Bytes::from(header.encode(&bytes)))
            }
            Err(e @ (RecordError::Unknown(_) | RecordError::PastEnd { .. })) => text_of(
                &HostMessage::error(ErrorCode::UnknownRecording, e.to_string()),
            ),
            Err(e @ RecordError::StillWriting(_)) => {
                text_of(&HostMessage::error(ErrorCode::NotAllowedNow, e.to_string()))
            }
            Err(e) => {
                tracing::warn!("a recording could not be read: {e}");
                let why = format!("{name} could not be read at the Host");
                text_of(&HostMessage::error(ErrorCode::UnknownRecording, why))
            }
        }
    }
}
