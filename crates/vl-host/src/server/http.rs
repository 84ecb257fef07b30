//! The Host's one web page, on its WebSocket port: `GET /status`, the
//! administrator's view as JSON (for `vl host status`, `curl`, a
//! monitoring probe). Each connection's first bytes are read as an HTTP
//! request head; a WebSocket upgrade goes on to the handshake with those
//! bytes given back, anything else is answered here and closed. At a lab
//! with accounts only an administrator's (HTTP Basic) credentials open
//! the page, checked by the same gate as a hello: slowly when wrong, and
//! limited per address and account.

use std::io;
use std::net::IpAddr;
use std::pin::Pin;
use std::task::{Context, Poll};

use base64::Engine;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::sync::{mpsc, oneshot};
use vl_core::{ErrorCode, Role};

use super::Io;
use super::hub::ToHub;
use crate::accounts::gate::{Credentials, Gate, Identity};
use crate::accounts::users::AccountRole;

/// The most a request head may be: a WebSocket upgrade is a few hundred bytes.
const MAX_HEAD: usize = 8 << 10;
const MAX_HEADERS: usize = 32;

/// What a connection opened with.
pub(super) enum Opening {
    /// A WebSocket upgrade: the stream, its head read back first.
    WebSocket(Box<dyn Io>),
    /// A plain request, answered here.
    Page(Box<dyn Io>, Page),
}

/// A plain request.
pub(super) struct Page {
    path: String,
    /// HTTP Basic credentials: user and password.
    basic: Option<(String, String)>,
}

/// Reads the request head from `stream` and says what it asks for.
pub(super) async fn opening(mut stream: Box<dyn Io>) -> io::Result<Opening> {
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    loop {
        let n = stream.read(&mut chunk).await?;
        if n == 0 {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        head.extend_from_slice(&chunk[..n]);
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        let mut request = httparse::Request::new(&mut headers);
        match request.parse(&head) {
            Ok(httparse::Status::Complete(_)) => {
                let header = |name: &str| {
                    request
                        .headers
                        .iter()
                        .find(|h| h.name.eq_ignore_ascii_case(name))
                        .and_then(|h| std::str::from_utf8(h.value).ok())
                };
                if header("upgrade").is_some_and(|v| v.eq_ignore_ascii_case("websocket")) {
                    return Ok(Opening::WebSocket(Box::new(Rewind {
                        head,
                        read: 0,
                        stream,
                    })));
                }
                let page = Page {
                    path: request.path.unwrap_or("/").to_owned(),
                    basic: header("authorization").and_then(basic),
                };
                return Ok(Opening::Page(stream, page));
            }
            Ok(httparse::Status::Partial) if head.len() < MAX_HEAD => {}
            Ok(httparse::Status::Partial) => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    "request head too large",
                ));
            }
            Err(e) => return Err(io::Error::new(io::ErrorKind::InvalidData, e)),
        }
    }
}

/// The user and password of a `Basic` authorization.
fn basic(value: &str) -> Option<(String, String)> {
    let (scheme, encoded) = value.trim().split_once(' ')?;
    if !scheme.eq_ignore_ascii_case("basic") {
        return None;
    }
    let decoded = base64::engine::general_purpose::STANDARD
        .decode(encoded.trim())
        .ok()?;
    let text = String::from_utf8(decoded).ok()?;
    let (user, password) = text.split_once(':')?;
    Some((user.to_owned(), password.to_owned()))
}

/// Answers `page`: the status to whom may see it, else why not.
pub(super) async fn answer(
    mut stream: Box<dyn Io>,
    page: Page,
    (connection, address): (u64, IpAddr),
    gate: &Gate,
    hub: &mpsc::Sender<ToHub>,
) -> io::Result<()> {
    let (status, extra, body) = if page.path.split('?').next() != Some("/status") {
        (
            "404 Not Found",
            "",
            "this is a vl Host: Guests connect here by WebSocket; GET /status shows its state\n"
                .to_owned(),
        )
    } else {
        match admitted(&page, (connection, address), gate).await {
            Err((code, why)) => (
                if code == ErrorCode::TooManyAttempts {
                    "429 Too Many Requests"
                } else {
                    "401 Unauthorized"
                },
                "WWW-Authenticate: Basic realm=\"vl host\", charset=\"UTF-8\"\r\n",
                format!("{why}\n"),
            ),
            Ok(()) => {
                let (tx, rx) = oneshot::channel();
                let status = match hub.send(ToHub::Status(tx)).await {
                    Ok(()) => rx.await.ok(),
                    Err(_) => None,
                };
                match status.and_then(|s| serde_json::to_string(&s).ok()) {
                    Some(json) => ("200 OK", "Content-Type: application/json\r\n", json),
                    None => (
                        "503 Service Unavailable",
                        "",
                        "the Host is stopping\n".into(),
                    ),
                }
            }
        }
    };
    let reply = format!(
        "HTTP/1.1 {status}\r\n{extra}Content-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(reply.as_bytes()).await?;
    stream.shutdown().await
}

/// Whether `page`'s credentials open the status: anyone's at a lab
/// without accounts, an administrator's at one with them.
async fn admitted(
    page: &Page,
    (connection, address): (u64, IpAddr),
    gate: &Gate,
) -> Result<(), (ErrorCode, String)> {
    if !gate.has_accounts() {
        return Ok(());
    }
    let Some((user, password)) = &page.basic else {
        return Err((
            ErrorCode::Unauthorized,
            "the status is the lab administrator's: log in (HTTP Basic)".into(),
        ));
    };
    let credentials = Credentials {
        role: Role::Observer,
        user: Some(user),
        password: Some(password),
        token: None,
    };
    let admitted = gate
        .check(connection, address, credentials)
        .await
        .map_err(|refused| (refused.code, refused.why))?;
    match admitted.identity {
        Identity::Account {
            role: AccountRole::Admin,
            ..
        } => Ok(()),
        _ => Err((
            ErrorCode::Unauthorized,
            format!("{user} is not an administrator of this lab"),
        )),
    }
}

/// A stream whose first bytes, already read, are read again.
struct Rewind {
    head: Vec<u8>,
    read: usize,
    stream: Box<dyn Io>,
}

impl AsyncRead for Rewind {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        if self.read < self.head.len() {
            let n = buf.remaining().min(self.head.len() - self.read);
            let start = self.read;
            buf.put_slice(&self.head[start..start + n]);
            self.read += n;
            return Poll::Ready(Ok(()));
        }
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for Rewind {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basic_credentials_are_read_and_others_are_not() {
        assert_eq!(
            basic("Basic cm9vdDpzM2NyZXQ6eA=="),
            Some(("root".into(), "s3cret:x".into()))
        );
        assert_eq!(basic("Bearer cm9vdDpz"), None);
        assert_eq!(basic("Basic !!!"), None);
        assert_eq!(basic("Basic"), None);
    }
}
