//! The Guest's side of the Media: a WebSocket connection to a Host that
//! turns the socket into channels of typed messages. It answers the Host's
//! pings itself and measures the round-trip time with its own.
//!
//! Opening a connection returns at once; connecting happens on the
//! connection's task, and a Host that cannot be reached arrives as
//! [`Incoming::Unreachable`], so a window can show it and offer to retry.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use crate::dial::Target;

mod remembered;
use futures_util::{SinkExt, StreamExt};
use remembered::Remembered;
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::{self, Message};
use vl_core::{
    FrameHeader, GuestMessage, HostMessage, MAX_FRAME_BYTES, MAX_TEXT_BYTES, PartHeader, Role, Wire,
};

/// How often the Guest measures the round trip.
const PING_EVERY: Duration = Duration::from_millis(200);
/// How long a Host has to accept the connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// What arrives from the Host.
#[derive(Debug, Clone)]
pub enum Incoming {
    Message(Box<HostMessage>),
    /// A camera frame: its header and encoded image bytes.
    Frame(FrameHeader, Vec<u8>),
    /// A part of a recording asked for with `download`.
    Part(PartHeader, Vec<u8>),
    /// A round trip (ping → pong) took this many ms.
    RoundTrip(f64),
    /// The Host has not been reached yet: trying again (attempt 1, 2, …)
    /// in `wait`.
    Unreachable {
        error: ClientError,
        attempt: u32,
        wait: Duration,
    },
    /// The link dropped: connecting again (attempt 1, 2, …) in `wait`.
    Reconnecting {
        attempt: u32,
        wait: Duration,
        reason: String,
    },
    /// The connection ended for good, and why.
    Closed(String),
}

impl Incoming {
    /// Says on stderr that the Host does not answer or the link dropped,
    /// when `progress` is shown (a headless Guest's).
    pub(crate) fn tell(&self, progress: bool) {
        if let Some(trouble) = self.trouble().filter(|_| progress) {
            eprintln!("{trouble}");
        }
    }

    /// What a person is told of a link in trouble: the Host does not
    /// answer yet, or the link dropped and is tried again.
    pub fn trouble(&self) -> Option<String> {
        match self {
            Incoming::Reconnecting {
                attempt,
                reason,
                wait,
            } => Some(format!(
                "link lost ({reason}): reconnecting in {:.2} s, attempt {attempt}",
                wait.as_secs_f64()
            )),
            Incoming::Unreachable { attempt, wait, .. } => Some(format!(
                "no Host answers yet: trying again in {:.2} s, attempt {attempt}",
                wait.as_secs_f64()
            )),
            _ => None,
        }
    }
}

/// Why there is no connection to a Host.
#[derive(Debug, Clone, Error, PartialEq, Eq)]
pub enum ClientError {
    #[error("'{url}' is not a Host's address: {why}")]
    BadUrl { url: String, why: String },
    #[error("cannot connect to {url}: {cause}")]
    Connect { url: String, cause: String },
}

impl ClientError {
    /// Whether the address itself is no Host's: the user's to fix.
    pub fn is_bad_address(&self) -> bool {
        matches!(self, ClientError::BadUrl { .. })
    }
}

/// Checks that `url` is one a Host listens on, with a hint when it is not.
fn check_url(url: &str) -> Result<Target, ClientError> {
    Target::of(url).map_err(|why| ClientError::BadUrl {
        url: url.to_owned(),
        why,
    })
}

/// What went wrong, in words, said once: tungstenite's errors repeat
/// their cause in their source chain, and the system's carry error numbers.
fn cause(error: &tungstenite::Error) -> String {
    use tungstenite::Error;
    match error {
        Error::Io(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {
            "connection refused: is a vl Host listening there?".into()
        }
        Error::Io(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {
            "the connection was reset: the Host stopped or the network dropped it".into()
        }
        Error::Io(e) => e.kind().to_string(),
        Error::Http(response) => format!(
            "it answered HTTP {} instead of a WebSocket handshake: it is not a vl Host (check the address and port)",
            response.status()
        ),
        e if answered_not_as_a_host(e) => {
            "it answered, but it is not a vl Host (no WebSocket handshake): check the address and port"
                .into()
        }
        Error::Protocol(_) => "the connection closed before the handshake ended".into(),
        other => other.to_string(),
    }
}

/// Whether `error` is an answer no vl Host gives (plain HTTP, another
/// protocol), rather than a connection that failed or was cut short (a
/// relay closing during an outage).
fn answered_not_as_a_host(error: &tungstenite::Error) -> bool {
    use tungstenite::error::ProtocolError as P;
    match error {
        tungstenite::Error::Http(_) | tungstenite::Error::HttpFormat(_) => true,
        tungstenite::Error::Protocol(p) => matches!(
            p,
            P::WrongHttpMethod
                | P::WrongHttpVersion
                | P::MissingConnectionUpgradeHeader
                | P::MissingUpgradeWebSocketHeader
                | P::SecWebSocketAcceptKeyMismatch
        ),
        _ => false,
    }
}

/// What ended a connection that was up, in words.
fn lost(error: &tungstenite::Error) -> String {
    use tungstenite::Error;
    match error {
        Error::Io(_) => format!("connection lost: {}", cause(error)),
        Error::Protocol(_) => "the Host went without closing the connection".into(),
        other => format!("connection lost: {other}"),
    }
}

/// An open connection: send on `outgoing`, receive with
/// [`Connection::recv`] or [`Connection::try_recv`].
pub struct Connection {
    pub outgoing: mpsc::UnboundedSender<GuestMessage>,
    incoming: mpsc::UnboundedReceiver<Incoming>,
    waiting: Arc<Waiting>,
}

/// Camera frames and feedback received and not yet taken, at most: a
/// window that is not drawn (minimised, covered) takes nothing, and the
/// newest of either is what counts, so beyond these the new ones are
/// passed over rather than kept.
const FRAMES_WAITING: usize = 4;
const FEEDBACK_WAITING: usize = 64;

/// How many frames and feedback messages wait to be taken.
#[derive(Default)]
struct Waiting {
    frames: AtomicUsize,
    feedback: AtomicUsize,
}

impl Waiting {
    /// The counter `incoming` counts against, and its limit, if any.
    fn counter(&self, incoming: &Incoming) -> Option<(&AtomicUsize, usize)> {
        match incoming {
            Incoming::Frame(..) => Some((&self.frames, FRAMES_WAITING)),
            Incoming::Message(m) if matches!(**m, HostMessage::Feedback(_)) => {
                Some((&self.feedback, FEEDBACK_WAITING))
            }
            _ => None,
        }
    }

    /// Whether `incoming` may be queued; counts it if so.
    fn admit(&self, incoming: &Incoming) -> bool {
        let Some((n, most)) = self.counter(incoming) else {
            return true;
        };
        if n.fetch_add(1, Ordering::Relaxed) < most {
            return true;
        }
        n.fetch_sub(1, Ordering::Relaxed);
        false
    }

    /// `incoming` was taken.
    fn taken(&self, incoming: &Incoming) {
        if let Some((n, _)) = self.counter(incoming) {
            n.fetch_sub(1, Ordering::Relaxed);
        }
    }
}

impl Connection {
    /// A connection to no Host: nothing comes, what is sent goes nowhere
    /// (the window playing a recording back).
    pub fn detached() -> Connection {
        let (outgoing, _) = mpsc::unbounded_channel();
        let (_, incoming) = mpsc::unbounded_channel();
        Connection {
            outgoing,
            incoming,
            waiting: Arc::default(),
        }
    }

    /// The next thing from the Host; none once the connection's task ended.
    pub async fn recv(&mut self) -> Option<Incoming> {
        let incoming = self.incoming.recv().await?;
        self.waiting.taken(&incoming);
        Some(incoming)
    }

    /// The next thing from the Host, if one has come.
    pub fn try_recv(&mut self) -> Option<Incoming> {
        let incoming = self.incoming.try_recv().ok()?;
        self.waiting.taken(&incoming);
        Some(incoming)
    }

    /// Sends a message; a closed connection shows up as `Incoming::Closed`.
    pub fn send(&self, message: GuestMessage) {
        let _ = self.outgoing.send(message);
    }

    /// Says goodbye and waits (a second at most) until the connection has
    /// closed, so the Host frees an operator's role at once rather than
    /// holding it for a link that dropped.
    pub async fn close(mut self) {
        let _ = self.outgoing.send(GuestMessage::Bye);
        let _ = tokio::time::timeout(GOODBYE, async {
            while let Some(incoming) = self.recv().await {
                if matches!(incoming, Incoming::Closed(_)) {
                    return;
                }
            }
        })
        .await;
    }
}

/// How long a Guest that ends lets its connection's goodbye go out.
pub const GOODBYE_WAIT: Duration = Duration::from_millis(300);

/// How long a goodbye may take.
const GOODBYE: Duration = Duration::from_secs(1);

/// How long a Guest that closes waits for the Host's close, within
/// `GOODBYE`.
const CLOSING: Duration = Duration::from_millis(800);

/// The first wait before reconnecting; it doubles up to `RECONNECT_MAX`.
const RECONNECT_FIRST: Duration = Duration::from_millis(250);
const RECONNECT_MAX: Duration = Duration::from_secs(4);

type HostSocket = tokio_tungstenite::WebSocketStream<Box<dyn vl_core::Io>>;

/// Why serving a connection stopped.
enum Ended {
    /// The Guest closed it or said bye: it is over.
    Deliberately(String),
    /// The link dropped or the Host went: worth connecting again.
    Lost(String),
}

/// How a connection that was served ended, and whether a Host welcomed
/// the Guest on it (a relay whose Host is down accepts and closes at once:
/// that is no link up, and the back-off goes on growing).
struct Served {
    ended: Ended,
    welcomed: bool,
}

/// Opens a connection to the Host at `url` (ws://host:port): connecting
/// and then serving the socket run on a task of the current tokio runtime.
/// Only an address that cannot be a Host's is refused here.
///
/// A Host that cannot be reached is tried again with back-off
/// ([`Incoming::Unreachable`] says so each time); messages sent before the
/// first connection is up wait for it. A connection that drops once it
/// was up is made again the same way, saying the last hello again (with
/// the operator's `resume` from its welcome, so the Host gives the role
/// and the run back); [`Incoming::Reconnecting`] says so meanwhile. What
/// is sent while an established link is down is dropped: a command must
/// not arrive late. [`Connection::close`] says goodbye.
pub fn open(url: &str) -> Result<Connection, ClientError> {
    let target = check_url(url)?;
    let (outgoing, mut to_send) = mpsc::unbounded_channel::<GuestMessage>();
    let (to_guest, incoming) = mpsc::unbounded_channel();
    let waiting = Arc::new(Waiting::default());
    let deliver = Deliver {
        to: to_guest,
        waiting: waiting.clone(),
    };
    let url = url.to_owned();
    tokio::spawn(async move {
        let mut remembered = Remembered::default();
        let mut ever_welcomed = false;
        let mut attempt = 0u32;
        let mut wait = RECONNECT_FIRST;
        loop {
            let why = match connect(&target).await {
                // Something answered that is no vl Host: trying again
                // will not change that.
                Err(NotConnected::NotAHost(cause)) => {
                    let _ = deliver.send(Incoming::Closed(format!("{url}: {cause}")));
                    return;
                }
                Err(NotConnected::Unreachable(cause)) => cause,
                Ok(ws) => {
                    let again = remembered.hello_again();
                    let served = serve(ws, again, &mut remembered, &mut to_send, &deliver).await;
                    if served.welcomed {
                        // The link was up: back-off starts afresh.
                        ever_welcomed = true;
                        attempt = 0;
                        wait = RECONNECT_FIRST;
                    }
                    match served.ended {
                        Ended::Deliberately(reason) => {
                            let _ = deliver.send(Incoming::Closed(reason));
                            return;
                        }
                        Ended::Lost(reason) => reason,
                    }
                }
            };
            attempt += 1;
            let told = if ever_welcomed {
                Incoming::Reconnecting {
                    attempt,
                    wait,
                    reason: why,
                }
            } else {
                Incoming::Unreachable {
                    error: ClientError::Connect {
                        url: url.clone(),
                        cause: why,
                    },
                    attempt,
                    wait,
                }
            };
            if deliver.send(told).is_err() {
                return;
            }
            // Until a hello has gone out, what the Guest sent waits for
            // the first connection; after, it would arrive late.
            let keep = remembered.hello.is_none();
            if !wait_while_down(&mut to_send, wait, keep).await {
                let _ = deliver.send(Incoming::Closed("closed by the Guest".into()));
                return;
            }
            wait = (wait * 2).min(RECONNECT_MAX);
        }
    });
    Ok(Connection {
        outgoing,
        incoming,
        waiting,
    })
}

/// Why a connection was not made.
enum NotConnected {
    /// Nothing answered (yet): worth trying again.
    Unreachable(String),
    /// Something answered, not as a vl Host does.
    NotAHost(String),
}

/// Hands what arrives to the Guest, passing over frames and feedback
/// beyond what may wait.
struct Deliver {
    to: mpsc::UnboundedSender<Incoming>,
    waiting: Arc<Waiting>,
}

impl Deliver {
    /// Queues `incoming`; an error when the Guest has gone.
    fn send(&self, incoming: Incoming) -> Result<(), ()> {
        if !self.waiting.admit(&incoming) {
            return Ok(());
        }
        self.to.send(incoming).map_err(|_| ())
    }
}

/// Connects to `target`, within the connect timeout.
async fn connect(target: &Target) -> Result<HostSocket, NotConnected> {
    let config = WebSocketConfig::default()
        .max_message_size(Some(MAX_TEXT_BYTES.max(MAX_FRAME_BYTES)))
        .max_frame_size(Some(MAX_TEXT_BYTES.max(MAX_FRAME_BYTES)));
    let connecting = async {
        let stream = target.dial().await.map_err(|e| match e.get_ref() {
            // A certificate that is not the pinned one will not become it.
            Some(inner) if inner.is::<rustls::Error>() => NotConnected::NotAHost(e.to_string()),
            _ => NotConnected::Unreachable(cause(&tungstenite::Error::Io(e))),
        })?;
        tokio_tungstenite::client_async_with_config(target.url.as_str(), stream, Some(config))
            .await
            .map_err(|e| match answered_not_as_a_host(&e) {
                true => NotConnected::NotAHost(cause(&e)),
                false => NotConnected::Unreachable(cause(&e)),
            })
    };
    match tokio::time::timeout(CONNECT_TIMEOUT, connecting).await {
        Ok(Ok((ws, _))) => Ok(ws),
        Ok(Err(refused)) => Err(refused),
        Err(_) => Err(NotConnected::Unreachable(format!(
            "no answer within {} s",
            CONNECT_TIMEOUT.as_secs()
        ))),
    }
}

/// Waits `wait` with the link down, dropping what the Guest sends
/// meanwhile unless told to `keep` it; false when the Guest closed or
/// said bye.
async fn wait_while_down(
    to_send: &mut mpsc::UnboundedReceiver<GuestMessage>,
    wait: Duration,
    keep: bool,
) -> bool {
    if keep {
        tokio::time::sleep(wait).await;
        return !to_send.is_closed();
    }
    let until = tokio::time::Instant::now() + wait;
    loop {
        tokio::select! {
            () = tokio::time::sleep_until(until) => return true,
            message = to_send.recv() => match message {
                None | Some(GuestMessage::Bye) => return false,
                Some(_) => {}
            },
        }
    }
}

/// Serves one connection: says `first` (a hello again) if given, then
/// carries messages both ways until it ends.
async fn serve(
    ws: HostSocket,
    first: Option<GuestMessage>,
    remembered: &mut Remembered,
    to_send: &mut mpsc::UnboundedReceiver<GuestMessage>,
    deliver: &Deliver,
) -> Served {
    let mut welcomed = false;
    let ended = carry(ws, first, remembered, to_send, deliver, &mut welcomed).await;
    Served { ended, welcomed }
}

/// Carries messages both ways on `ws` until it ends; `welcomed` is set
/// when the Host welcomes the Guest.
async fn carry(
    ws: HostSocket,
    first: Option<GuestMessage>,
    remembered: &mut Remembered,
    to_send: &mut mpsc::UnboundedReceiver<GuestMessage>,
    deliver: &Deliver,
    welcomed: &mut bool,
) -> Ended {
    let (mut sink, mut source) = ws.split();
    let clock = Instant::now();
    let mut ping = tokio::time::interval(PING_EVERY);
    let text = |m: &GuestMessage| Message::text(m.encode());
    if let Some(hello) = first
        && let Err(e) = sink.send(text(&hello)).await
    {
        return Ended::Lost(format!("send failed: {e}"));
    }
    loop {
        tokio::select! {
            message = to_send.recv() => match message {
                Some(message) => {
                    let bye = message == GuestMessage::Bye;
                    match message {
                        GuestMessage::Hello { .. } => remembered.hello = Some(message.clone()),
                        GuestMessage::Queue => remembered.in_line = true,
                        GuestMessage::LeaveQueue => remembered.in_line = false,
                        _ => {}
                    }
                    if let Err(e) = sink.send(text(&message)).await {
                        return Ended::Lost(format!("send failed: {e}"));
                    }
                    if bye {
                        close(&mut sink, &mut source).await;
                        return Ended::Deliberately("said bye".to_owned());
                    }
                }
                None => {
                    close(&mut sink, &mut source).await;
                    return Ended::Deliberately("closed by the Guest".to_owned());
                }
            },
            received = source.next() => match received {
                None => return Ended::Lost("the Host closed the connection".to_owned()),
                Some(Err(e)) => return Ended::Lost(lost(&e)),
                Some(Ok(Message::Text(t))) => match HostMessage::decode(t.as_str()) {
                    Ok(HostMessage::Ping { t }) => {
                        if let Err(e) = sink.send(text(&GuestMessage::Pong { t })).await {
                            return Ended::Lost(format!("send failed: {e}"));
                        }
                    }
                    Ok(HostMessage::Pong { t }) => {
                        let rtt = clock.elapsed().as_secs_f64() * 1e3 - t;
                        let _ = deliver.send(Incoming::RoundTrip(rtt));
                    }
                    Ok(HostMessage::Bye) => return Ended::Lost("the Host said bye".to_owned()),
                    // Not an error to show: the place in line that follows says it.
                    Ok(message) if !*welcomed && let Some(hello) = remembered.watch_and_queue(&message) => {
                        if let Err(e) = sink.send(text(&hello)).await {
                            return Ended::Lost(format!("send failed: {e}"));
                        }
                    }
                    Ok(message) => {
                        remembered.heard(&message);
                        let queue = match &message {
                            HostMessage::Welcome { role, .. } => {
                                *welcomed = true;
                                *role == Role::Observer && remembered.in_line
                            }
                            _ => false,
                        };
                        let _ = deliver.send(Incoming::Message(Box::new(message)));
                        if queue && let Err(e) = sink.send(text(&GuestMessage::Queue)).await {
                            return Ended::Lost(format!("send failed: {e}"));
                        }
                    }
                    Err(e) => tracing::warn!("ignoring a message from the Host: {e}"),
                },
                Some(Ok(Message::Binary(bytes))) if PartHeader::is_part(&bytes) => match PartHeader::decode(&bytes) {
                    Ok((header, part)) => {
                        let _ = deliver.send(Incoming::Part(header, part.to_vec()));
                    }
                    Err(e) => tracing::warn!("ignoring a recording's part from the Host: {e}"),
                },
                Some(Ok(Message::Binary(bytes))) => match FrameHeader::decode(&bytes) {
                    Ok((header, image)) => {
                        let _ = deliver.send(Incoming::Frame(header, image.to_vec()));
                    }
                    Err(e) => tracing::warn!("ignoring a frame from the Host: {e}"),
                },
                // A relay in front of the Host says why it closes.
                Some(Ok(Message::Close(Some(frame)))) if !frame.reason.is_empty() => {
                    return Ended::Lost(frame.reason.to_string());
                }
                Some(Ok(Message::Close(_))) => return Ended::Lost("the Host closed the connection".to_owned()),
                Some(Ok(_)) => {}
            },
            _ = ping.tick() => {
                let t = clock.elapsed().as_secs_f64() * 1e3;
                if let Err(e) = sink.send(text(&GuestMessage::Ping { t })).await {
                    return Ended::Lost(format!("send failed: {e}"));
                }
            }
        }
    }
}

/// Closes `ws` as WebSocket means it to be: the Guest's close, then
/// reading on (a while at most) until the Host answers with its own. The
/// Host answers once it has taken in all the Guest sent, a `bye` included;
/// a socket dropped sooner, with frames still unread, is reset, and the
/// Host may see a link that dropped instead of a goodbye and hold the
/// operator's role for them.
async fn close(
    sink: &mut futures_util::stream::SplitSink<HostSocket, Message>,
    source: &mut futures_util::stream::SplitStream<HostSocket>,
) {
    let _ = sink.send(Message::Close(None)).await;
    let _ = tokio::time::timeout(CLOSING, async {
        while let Some(Ok(_)) = source.next().await {}
    })
    .await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_and_feedback_wait_only_so_many() {
        let waiting = Waiting::default();
        let frame = || {
            let header = FrameHeader {
                format: vl_core::ImageFormat::Jpeg,
                width: 1,
                height: 1,
                seq: 1,
                event: 0,
                capture_us: 0,
            };
            Incoming::Frame(header, Vec::new())
        };
        let admitted = (0..10).filter(|_| waiting.admit(&frame())).count();
        assert_eq!(admitted, FRAMES_WAITING);
        waiting.taken(&frame());
        assert!(waiting.admit(&frame()), "one taken makes room for one");
        assert!(!waiting.admit(&frame()));
        // Everything else always waits: a run's end is never passed over.
        let done = Incoming::Closed("bye".into());
        assert!((0..1000).all(|_| waiting.admit(&done)));
    }

    /// A Guest that closes waits for the Host's close, reading the frames
    /// it had not read: a socket dropped with them unread is reset, which
    /// can lose the bye it sent and fails the Host's close.
    #[tokio::test]
    async fn closing_waits_for_the_hosts_close() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let url = format!("ws://{}", listener.local_addr().unwrap());
        let host = tokio::spawn(async move {
            let (tcp, _) = listener.accept().await.unwrap();
            let ws = tokio_tungstenite::accept_async(tcp).await.unwrap();
            let (mut sink, mut source) = ws.split();
            // Frames all the while, as the camera's.
            let mut frame = tokio::time::interval(Duration::from_millis(1));
            let mut heard = Vec::new();
            loop {
                tokio::select! {
                    _ = frame.tick() => {
                        if let Err(e) = sink.send(Message::binary(vec![0u8; 16384])).await {
                            return Err(format!("a frame: {e} after {heard:?}"));
                        }
                    }
                    message = source.next() => match message {
                        Some(Ok(Message::Text(t))) => heard.push(t.to_string()),
                        Some(Ok(Message::Close(_))) => break,
                        Some(Ok(_)) => {}
                        other => return Err(format!("{other:?} after {heard:?}")),
                    },
                }
            }
            // The Host tells its hub before it answers the close.
            tokio::time::sleep(Duration::from_millis(100)).await;
            sink.flush()
                .await
                .map_err(|e| format!("answering the close: {e}"))?;
            Ok(heard)
        });
        let connection = open(&url).unwrap();
        tokio::time::sleep(Duration::from_millis(200)).await;
        connection.close().await;
        let heard = host.await.unwrap().unwrap();
        assert_eq!(heard.last(), Some(&GuestMessage::Bye.encode()), "{heard:?}");
    }

    #[test]
    fn addresses_that_cannot_be_a_host_get_a_hint() {
        assert!(check_url("ws://127.0.0.1:7400").is_ok());
        assert!(check_url("wss://lab.example:7400").is_ok());
        let hint = |url: &str| check_url(url).unwrap_err().to_string();
        assert_eq!(
            hint("127.0.0.1:7400"),
            "'127.0.0.1:7400' is not a Host's address: it has no scheme: try ws://127.0.0.1:7400"
        );
        assert!(hint("ws://lab.example:7400/#pin=ab").contains("SHA-256"));
        assert!(hint("http://lab:7400").contains("try ws://lab:7400"));
        assert!(hint("ws://").contains("names no host"));
    }
}
