//! The answer of a Host with no room for one more connection: HTTP 503
//! with `Retry-After`, so a browser or a script can tell "busy, try
//! again" from "down", and a page loaded then tries again by itself (the
//! web Guest's socket already does, backing off). Given to a connection
//! refused a slot (every slot holds a welcomed client), and to one pushed
//! out while still shaking hands (`admission`: the oldest silent one of
//! its address). Answering costs the Host: at most `ANSWERING` refusals
//! are answered at once, each for at most `LINGER`; others are closed.

use std::sync::Arc;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::sync::Semaphore;

/// How long a refused client is asked to wait before trying again.
pub(crate) const RETRY_AFTER_S: u64 = 2;
/// Refusals answered at once.
const ANSWERING: usize = 32;
/// The most one refusal takes: its TLS handshake, the answer, and reading
/// what the client still sends (closing on unread bytes would reset the
/// connection and lose the answer).
const LINGER: Duration = Duration::from_secs(1);

static PERMITS: Semaphore = Semaphore::const_new(ANSWERING);

/// The answer, a page that loads itself again after `RETRY_AFTER_S`.
fn answer() -> String {
    let body = format!(
        "<!doctype html><meta charset=\"utf-8\"><meta http-equiv=\"refresh\" content=\"{RETRY_AFTER_S}\">\
         <title>The lab is busy</title><p>The lab has no room for one more connection just now; \
         this page tries again in {RETRY_AFTER_S} s.</p>\n"
    );
    format!(
        "HTTP/1.1 503 Service Unavailable\r\nRetry-After: {RETRY_AFTER_S}\r\n\
         Content-Type: text/html; charset=utf-8\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
}

/// Answers `stream` 503 in a task of its own (over TLS at a lab that
/// speaks it), or closes it when `ANSWERING` are being answered.
pub(crate) fn refuse(stream: TcpStream, tls: Option<Arc<rustls::ServerConfig>>) {
    let Ok(permit) = PERMITS.try_acquire() else {
        return;
    };
    tokio::spawn(async move {
        let _permit = permit;
        let _ = tokio::time::timeout(LINGER, async move {
            match tls {
                Some(tls) => {
                    if let Ok(stream) = tokio_rustls::TlsAcceptor::from(tls).accept(stream).await {
                        tell(stream).await;
                    }
                }
                None => tell(stream).await,
            }
        })
        .await;
    });
}

/// A second handle on a plain connection's socket, kept while it shakes
/// hands, to answer 503 on if it is pushed out meanwhile (the handshake
/// owns the connection). None over TLS: the answer would need the TLS
/// session the handshake holds, so such a connection is only closed.
pub(crate) fn spare(stream: &TcpStream, tls: bool) -> Option<std::net::TcpStream> {
    if tls {
        return None;
    }
    socket2::SockRef::from(stream)
        .try_clone()
        .ok()
        .map(Into::into)
}

/// Answers the spare handle, if any, of a connection pushed out while
/// shaking hands.
pub(crate) fn refuse_spare(spare: Option<std::net::TcpStream>) {
    if let Some(Ok(stream)) = spare.map(TcpStream::from_std) {
        refuse(stream, None);
    }
}

async fn tell<S: AsyncRead + AsyncWrite + Unpin>(mut stream: S) {
    if stream.write_all(answer().as_bytes()).await.is_err() {
        return;
    }
    let _ = stream.shutdown().await;
    let mut sink = [0u8; 1024];
    while matches!(stream.read(&mut sink).await, Ok(n) if n > 0) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_answer_says_how_long_to_wait() {
        let answer = answer();
        let (head, body) = answer.split_once("\r\n\r\n").unwrap();
        assert!(head.starts_with("HTTP/1.1 503 "));
        assert!(head.contains(&format!("Retry-After: {RETRY_AFTER_S}\r\n")));
        assert!(head.contains(&format!("Content-Length: {}\r", body.len())));
    }
}
