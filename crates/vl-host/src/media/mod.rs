//! The Media in the loop: a WebSocket relay between Guests and a Host that
//! holds every message for the delay the link model gives it (thesis §3.5:
//! the Internet's random delay is what event-based control must survive).
//! Each connection's two directions are separate `MessageLink`s, so a
//! message keeps TCP's order and a lost packet shows as a retransmission's
//! wait; a scheduled disconnect closes every connection and refuses new ones
//! until it ends. What the relay costs by itself, and whether it keeps to
//! its model on real messages, is measured in `bench`.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use futures_util::stream::{SplitSink, SplitStream};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_tungstenite::WebSocketStream;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::protocol::{CloseFrame, WebSocketConfig};
use tokio_tungstenite::tungstenite::{self, Message};
use tracing::{debug, warn};
use vl_core::{MAX_FRAME_BYTES, MAX_TEXT_BYTES, PART_BYTES, PartHeader};
use vl_sim::{Delivery, LinkModel, MessageLink};

use crate::server::admission::{Admission, Ticket};
use crate::server::socket::{self, Unwritten};

mod bench;

pub use bench::{MediaBench, MediaBenchError, RelayRoundTrip, Reproduced, bench};

/// Bytes of text (and recordings' parts) one direction of a connection may
/// hold in flight (besides one message however large): what a slow link
/// holds of the feedback, a definition and a part; a link slower than what
/// is sent into it closes rather than grow without end.
const IN_FLIGHT_BYTES: usize = MAX_TEXT_BYTES + PART_BYTES;
/// Bytes of camera frames one direction holds on their way (the link's
/// delay); a frame whose time came while the client did not read is let
/// go when a newer one comes, so a client that does not read costs the
/// newest frame, as it would at the Host itself.
const FRAME_BYTES_HELD: usize = 2 << 20;
/// How long the handshakes on either side may take.
const HANDSHAKE: Duration = Duration::from_secs(10);
/// How long a Guest has to answer the Media's close.
const CLOSING: Duration = Duration::from_secs(1);
/// Timers wake within a millisecond; the last stretch before a message is
/// due is waited out by yielding, so delays are kept to a few microseconds.
const SPIN: Duration = Duration::from_micros(1500);

/// Why the relay could not start.
#[derive(Debug, thiserror::Error)]
pub enum MediaError {
    #[error("cannot listen on {0}: {1}")]
    Bind(SocketAddr, std::io::Error),
    #[error("the upstream Host's address '{0}' is not ws://HOST:PORT")]
    Upstream(String),
}

/// What the relay puts between its clients and the Host.
#[derive(Debug, Clone)]
pub struct MediaConfig {
    /// The Host's WebSocket URL.
    pub upstream: String,
    /// Each direction's link.
    pub model: LinkModel,
    /// Connection k's links are seeded `seed + 2k` (to the Host) and `seed + 2k + 1`.
    pub seed: u64,
}

/// Delays kept per direction for the time analysis; later ones are not kept.
const DELAYS_KEPT: usize = 1 << 20;

/// How long each message the relay carried was held, ms, measured at the
/// relay on one clock: the one-way delay each leg saw.
#[derive(Debug, Clone, Default)]
pub struct Delays {
    pub to_host: Vec<f64>,
    /// Text messages to the Guest: feedback, replies, pings.
    pub to_guest: Vec<f64>,
    /// Camera frames to the Guest.
    pub frames_to_guest: Vec<f64>,
}

/// A relay, listening and relaying in the background.
pub struct Media {
    pub addr: SocketAddr,
    task: tokio::task::JoinHandle<()>,
    delays: Arc<Mutex<Delays>>,
}

impl Media {
    /// Binds `listen` and relays every connection to `config.upstream`.
    pub async fn start(listen: SocketAddr, config: MediaConfig) -> Result<Media, MediaError> {
        if !config.upstream.starts_with("ws://") {
            return Err(MediaError::Upstream(config.upstream));
        }
        let listener = TcpListener::bind(listen)
            .await
            .map_err(|e| MediaError::Bind(listen, e))?;
        let addr = listener
            .local_addr()
            .map_err(|e| MediaError::Bind(listen, e))?;
        let delays = Arc::new(Mutex::new(Delays::default()));
        let task = tokio::spawn(relay(listener, Arc::new(config), delays.clone()));
        Ok(Media { addr, task, delays })
    }

    /// The delays of every message carried so far.
    pub fn delays(&self) -> Delays {
        self.delays.lock().map(|d| d.clone()).unwrap_or_default()
    }

    /// The URL Guests connect to instead of the Host's.
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// Relays until the process ends.
    pub async fn wait(mut self) {
        let _ = (&mut self.task).await;
    }
}

impl Drop for Media {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// The relay's clock: disconnects are scheduled on it.
#[derive(Clone, Copy)]
struct Clock(Instant);

impl Clock {
    fn ms(self) -> f64 {
        self.0.elapsed().as_secs_f64() * 1e3
    }

    fn at(self, ms: f64) -> Instant {
        self.0 + Duration::from_secs_f64(ms.max(0.0) / 1e3)
    }
}

async fn relay(listener: TcpListener, config: Arc<MediaConfig>, delays: Arc<Mutex<Delays>>) {
    let clock = Clock(Instant::now());
    // As at the Host, and as many connections: idle sockets from one address push out only each other.
    let admission = Admission::new();
    let mut k = 0u64;
    loop {
        let Ok((stream, peer)) = listener.accept().await else {
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        let up = MessageLink::new(config.model.clone(), config.seed.wrapping_add(2 * k));
        let down = MessageLink::new(config.model.clone(), config.seed.wrapping_add(2 * k + 1));
        k += 1;
        if up.down(clock.ms()) {
            debug!(%peer, "refused: the link is down");
            continue;
        }
        let Some(ticket) = admission.admit(k, peer.ip()) else {
            debug!(%peer, "refused: the relay carries as many connections as it can");
            continue;
        };
        let config = config.clone();
        let delays = delays.clone();
        tokio::spawn(async move {
            let links = (up, down);
            match connection(stream, &config, clock, links, ticket, &delays).await {
                Ok(why) => debug!(%peer, "relay ended: {why}"),
                Err(why) => debug!(%peer, "relay failed: {why}"),
            }
            crate::memory::give_back();
        });
    }
}

fn ws_config() -> WebSocketConfig {
    let most = MAX_TEXT_BYTES.max(MAX_FRAME_BYTES);
    WebSocketConfig::default()
        .max_message_size(Some(most))
        .max_frame_size(Some(most))
        .max_write_buffer_size(2 * most)
}

/// Relays one Guest's connection until either end closes or the link goes down.
async fn connection(
    stream: TcpStream,
    config: &MediaConfig,
    clock: Clock,
    (up, down): (MessageLink, MessageLink),
    ticket: Ticket,
    delays: &Mutex<Delays>,
) -> Result<&'static str, String> {
    let _ = stream.set_nodelay(true);
    let handshake = tokio::time::timeout(
        HANDSHAKE,
        tokio_tungstenite::accept_async_with_config(stream, Some(ws_config())),
    );
    let mut evicted = ticket.evicted.clone();
    let guest = tokio::select! {
        guest = handshake => guest
            .map_err(|_| "the Guest's handshake timed out".to_owned())?
            .map_err(|e| format!("the Guest's handshake failed: {e}"))?,
        _ = evicted.wait_for(|out| *out) => return Ok("pushed out before its handshake"),
    };
    // A Guest that shook hands is someone: it keeps its place.
    ticket.welcomed();
    let reached = tokio::time::timeout(
        HANDSHAKE,
        tokio_tungstenite::connect_async_with_config(&config.upstream, Some(ws_config()), true),
    )
    .await
    .map_err(|_| "did not answer".to_owned())
    .and_then(|r| {
        r.map_err(|e| match e {
            tungstenite::Error::Io(e) => format!("does not answer ({})", e.kind()),
            other => format!("does not answer as a vl Host ({other})"),
        })
    });
    let host = match reached {
        Ok((host, _)) => host,
        Err(why) => {
            // Said to the operator of the Media and to the Guest, who would
            // otherwise see only a connection that closes.
            let why = format!("the Host at {} {why}", config.upstream);
            warn!("{why}: the Guest's connection is closed");
            let mut guest = guest;
            let _ = guest
                .close(Some(CloseFrame {
                    code: CloseCode::Again,
                    reason: why.clone().into(),
                }))
                .await;
            // The closing handshake: a socket dropped while the Guest's
            // hello is on its way is reset, and the reset can overtake the
            // reason. Waiting for the Guest's own close lets it read why.
            let _ = tokio::time::timeout(CLOSING, async {
                while let Some(Ok(_)) = guest.next().await {}
            })
            .await;
            return Err(why);
        }
    };
    let (to_guest, from_guest) = guest.split();
    let (to_host, from_host) = host.split();
    let outage = next_outage(&config.model, clock);
    tokio::select! {
        r = carry(from_guest, to_host, up, clock, |ms, _| log(delays, ms, |d| &mut d.to_host)) => r,
        r = carry(from_host, to_guest, down, clock, |ms, frame| if frame {
            log(delays, ms, |d| &mut d.frames_to_guest)
        } else {
            log(delays, ms, |d| &mut d.to_guest)
        }) => r,
        () = outage => Ok("the link went down"),
    }
}

fn log(delays: &Mutex<Delays>, ms: f64, leg: fn(&mut Delays) -> &mut Vec<f64>) {
    if let Ok(mut d) = delays.lock() {
        let leg = leg(&mut d);
        if leg.len() < DELAYS_KEPT {
            leg.push(ms);
        }
    }
}

/// When the link next goes down (never, if no disconnect is scheduled).
async fn next_outage(model: &LinkModel, clock: Clock) {
    let now = clock.ms();
    match model
        .disconnects
        .iter()
        .map(|&(start, _)| start)
        .filter(|&start| start > now)
        .min_by(f64::total_cmp)
    {
        Some(start) => tokio::time::sleep_until(clock.at(start).into()).await,
        None => std::future::pending().await,
    }
}

type Source<S> = SplitStream<WebSocketStream<S>>;
type Sink<S> = SplitSink<WebSocketStream<S>, Message>;

/// Camera frames on their way in one direction, newest kept: the queue
/// carries their numbers, this holds their bytes within a budget.
#[derive(Default)]
struct FrameBudget {
    /// Each frame's number, when it is due, and the frame.
    held: std::collections::VecDeque<(u64, Instant, Message)>,
    bytes: usize,
    next: u64,
}

impl FrameBudget {
    /// Holds `frame`, due `at`: frames already due and not taken (the
    /// client is not reading) go, and the oldest past the budget; its number.
    fn hold(&mut self, frame: Message, at: Instant) -> u64 {
        let now = Instant::now();
        while let Some((_, due, old)) = self.held.front() {
            if *due > now && self.bytes <= FRAME_BYTES_HELD {
                break;
            }
            self.bytes -= old.len();
            self.held.pop_front();
        }
        let number = self.next;
        self.next += 1;
        self.bytes += frame.len();
        self.held.push_back((number, at, frame));
        number
    }

    /// Frame `number`, unless it was let go.
    fn take(&mut self, number: u64) -> Option<Message> {
        while let Some((n, _, _)) = self.held.front() {
            if *n > number {
                return None;
            }
            let (n, _, frame) = self.held.pop_front()?;
            self.bytes -= frame.len();
            if n == number {
                return Some(frame);
            }
        }
        None
    }
}

/// What waits in one direction's queue.
enum Carried {
    Text(Message),
    Frame(u64),
}

/// Carries one direction: each message is read at once, given its arrival
/// time by `link`, and written when that time comes.
async fn carry<A, B>(
    mut from: Source<A>,
    mut to: Sink<B>,
    mut link: MessageLink,
    clock: Clock,
    held: impl Fn(f64, bool),
) -> Result<&'static str, String>
where
    A: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin,
    B: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin,
{
    let (queue, mut due) = mpsc::unbounded_channel::<(Instant, Instant, Carried)>();
    let in_flight = AtomicUsize::new(0);
    let frames = Mutex::new(FrameBudget::default());
    let read = async {
        while let Some(message) = from.next().await {
            let message = message.map_err(|e| format!("read failed: {e}"))?;
            // Pings and pongs of the WebSocket itself are each hop's own.
            if matches!(
                message,
                Message::Ping(_) | Message::Pong(_) | Message::Frame(_)
            ) {
                continue;
            }
            let closing = message.is_close();
            let bytes = message.len();
            let at = match link.send(clock.ms(), bytes) {
                Delivery::At(ms) => clock.at(ms),
                Delivery::Disconnected => return Ok("the link went down"),
            };
            // Camera frames: the newest matters; text and recordings' parts
            // are each needed, within a budget.
            // Each message held gets bytes of its own: one read shares its
            // allocation with the socket's read buffer, so a small message
            // held while the other end does not read would keep whole
            // buffers of frames read around it.
            let message = owned(message);
            let carried = if matches!(&message, Message::Binary(b) if !PartHeader::is_part(b)) {
                let mut frames = frames.lock().map_err(|_| "frames lost".to_owned())?;
                Carried::Frame(frames.hold(message, at))
            } else {
                // One message, however large the socket let it be, always
                // goes; more than the budget with others does not.
                let before = in_flight.fetch_add(bytes, Ordering::Relaxed);
                if before > 0 && before + bytes > IN_FLIGHT_BYTES {
                    return Err("more in flight than the link can hold".to_owned());
                }
                Carried::Text(message)
            };
            let _ = queue.send((Instant::now(), at, carried));
            if closing {
                break;
            }
        }
        drop(queue);
        // Everything sent before the close is still delivered.
        std::future::pending::<Result<&'static str, String>>().await
    };
    let write = async {
        while let Some((read, at, carried)) = due.recv().await {
            wait_until(at).await;
            let message = match carried {
                Carried::Text(message) => {
                    in_flight.fetch_sub(message.len(), Ordering::Relaxed);
                    message
                }
                Carried::Frame(number) => {
                    let frame = frames.lock().ok().and_then(|mut f| f.take(number));
                    // A newer frame overtook it while the client did not read.
                    let Some(frame) = frame else { continue };
                    frame
                }
            };
            held(read.elapsed().as_secs_f64() * 1e3, message.is_binary());
            let closing = message.is_close();
            socket::write(&mut to, message).await.map_err(|e| match e {
                Unwritten::TimedOut => "the other end took nothing: it is not reading".to_owned(),
                Unwritten::Failed(e) => format!("write failed: {e}"),
            })?;
            if closing {
                return Ok("closed");
            }
        }
        Ok("closed")
    };
    tokio::select! {
        r = read => r,
        r = write => r,
    }
}

/// `message` with its payload copied out of whatever buffer it was read into.
fn owned(message: Message) -> Message {
    match message {
        Message::Text(text) => Message::text(text.as_str().to_owned()),
        Message::Binary(bytes) => Message::Binary(tungstenite::Bytes::copy_from_slice(&bytes)),
        other => other,
    }
}

/// Waits until `at`, to within microseconds.
async fn wait_until(at: Instant) {
    if let Some(early) = at.checked_sub(SPIN)
        && Instant::now() < early
    {
        tokio::time::sleep_until(early.into()).await;
    }
    while Instant::now() < at {
        tokio::task::yield_now().await;
    }
}
