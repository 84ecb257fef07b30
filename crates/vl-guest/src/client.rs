//! The Guest's side of the Media: a WebSocket connection to a Host that
//! turns the socket into channels of typed messages. It answers the Host's
//! pings itself and measures the round-trip time with its own.

use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::{self, Message};
use vl_core::frame::{FrameHeader, MAX_FRAME_BYTES};
use vl_core::protocol::{GuestMessage, HostMessage, MAX_TEXT_BYTES, Wire};

/// How often the Guest measures the round trip.
const PING_EVERY: Duration = Duration::from_millis(200);

/// What arrives from the Host.
#[derive(Debug, Clone)]
pub enum Incoming {
    Message(Box<HostMessage>),
    /// A camera frame: its header and encoded image bytes.
    Frame(FrameHeader, Vec<u8>),
    /// A round trip (ping → pong) took this many ms.
    RoundTrip(f64),
    /// The connection ended, and why.
    Closed(String),
}

#[derive(Debug, Error)]
pub enum ClientError {
    #[error("cannot connect to {url}: {source}")]
    Connect {
        url: String,
        source: tungstenite::Error,
    },
}

/// An open connection: send on `outgoing`, receive on `incoming`.
pub struct Connection {
    pub outgoing: mpsc::UnboundedSender<GuestMessage>,
    pub incoming: mpsc::UnboundedReceiver<Incoming>,
}

impl Connection {
    /// Sends a message; a closed connection shows up as `Incoming::Closed`.
    pub fn send(&self, message: GuestMessage) {
        let _ = self.outgoing.send(message);
    }
}

/// Connects to the Host at `url` (ws://host:port) and starts the
/// connection's task on the current tokio runtime.
pub async fn connect(url: &str) -> Result<Connection, ClientError> {
    let config = WebSocketConfig::default()
        .max_message_size(Some(MAX_TEXT_BYTES.max(MAX_FRAME_BYTES)))
        .max_frame_size(Some(MAX_TEXT_BYTES.max(MAX_FRAME_BYTES)));
    let (ws, _) = tokio_tungstenite::connect_async_with_config(url, Some(config), true)
        .await
        .map_err(|source| ClientError::Connect {
            url: url.to_owned(),
            source,
        })?;
    let (outgoing, mut to_send) = mpsc::unbounded_channel::<GuestMessage>();
    let (deliver, incoming) = mpsc::unbounded_channel();
    tokio::spawn(async move {
        let (mut sink, mut source) = ws.split();
        let clock = Instant::now();
        let mut ping = tokio::time::interval(PING_EVERY);
        let text = |m: &GuestMessage| Message::text(m.encode());
        let reason = loop {
            tokio::select! {
                message = to_send.recv() => match message {
                    Some(message) => {
                        let bye = message == GuestMessage::Bye;
                        if let Err(e) = sink.send(text(&message)).await {
                            break format!("send failed: {e}");
                        }
                        if bye {
                            let _ = sink.send(Message::Close(None)).await;
                            break "said bye".to_owned();
                        }
                    }
                    None => {
                        let _ = sink.send(Message::Close(None)).await;
                        break "closed by the Guest".to_owned();
                    }
                },
                received = source.next() => match received {
                    None => break "the Host closed the connection".to_owned(),
                    Some(Err(e)) => break format!("connection lost: {e}"),
                    Some(Ok(Message::Text(t))) => match HostMessage::decode(t.as_str()) {
                        Ok(HostMessage::Ping { t }) => {
                            if let Err(e) = sink.send(text(&GuestMessage::Pong { t })).await {
                                break format!("send failed: {e}");
                            }
                        }
                        Ok(HostMessage::Pong { t }) => {
                            let rtt = clock.elapsed().as_secs_f64() * 1e3 - t;
                            let _ = deliver.send(Incoming::RoundTrip(rtt));
                        }
                        Ok(HostMessage::Bye) => break "the Host said bye".to_owned(),
                        Ok(message) => {
                            let _ = deliver.send(Incoming::Message(Box::new(message)));
                        }
                        Err(e) => tracing::warn!("ignoring a message from the Host: {e}"),
                    },
                    Some(Ok(Message::Binary(bytes))) => match FrameHeader::decode(&bytes) {
                        Ok((header, image)) => {
                            let _ = deliver.send(Incoming::Frame(header, image.to_vec()));
                        }
                        Err(e) => tracing::warn!("ignoring a frame from the Host: {e}"),
                    },
                    Some(Ok(Message::Close(_))) => break "the Host closed the connection".to_owned(),
                    Some(Ok(_)) => {}
                },
                _ = ping.tick() => {
                    let t = clock.elapsed().as_secs_f64() * 1e3;
                    if let Err(e) = sink.send(text(&GuestMessage::Ping { t })).await {
                        break format!("send failed: {e}");
                    }
                }
            }
        };
        let _ = deliver.send(Incoming::Closed(reason));
    });
    Ok(Connection { outgoing, incoming })
}
