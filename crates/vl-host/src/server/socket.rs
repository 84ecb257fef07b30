//! A client's WebSocket as the Host holds it, and writing to it within a
//! time: a client that does not take a message in time is not reading (the
//! Host's rule, and the Media's for the Guests behind it).

use std::time::Duration;

use futures_util::SinkExt;
use futures_util::stream::SplitSink;
use tokio_tungstenite::WebSocketStream;
use tokio_tungstenite::tungstenite::{self, Message};

use vl_core::Io;

/// A client must take each message within this, or it is too slow to serve.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(5);

pub type Socket = WebSocketStream<Box<dyn Io>>;
pub type Sink = SplitSink<Socket, Message>;

/// Why a message was not written.
pub enum Unwritten {
    /// The client took nothing for the write timeout.
    TimedOut,
    Failed(tungstenite::Error),
}

/// Writes `message`, within the write timeout.
pub async fn write<S>(sink: &mut S, message: Message) -> Result<(), Unwritten>
where
    S: futures_util::Sink<Message, Error = tungstenite::Error> + Unpin,
{
    match tokio::time::timeout(WRITE_TIMEOUT, sink.send(message)).await {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(Unwritten::Failed(e)),
        Err(_) => Err(Unwritten::TimedOut),
    }
}
