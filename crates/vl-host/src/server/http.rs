//! What a connection to the Host's port opens with, and the pages served
//! there. Each connection's first bytes are read as an HTTP request head:
//! a WebSocket upgrade goes on to its handshake with those bytes given
//! back — a Foxglove client's (by its subprotocol) to the Foxglove server,
//! anyone else's to the Guests' protocol — and any other request is
//! answered by axum's router over hyper: the web Guest's files (`web`) and
//! `GET /status`, the administrator's view as JSON (for `vl host status`,
//! `curl`, a monitoring probe). At a lab with accounts only an
//! administrator's (HTTP Basic) credentials open the status, checked by
//! the same gate as a hello: slowly when wrong, and limited per address
//! and account.

use std::io;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

use axum::Router;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use base64::Engine;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::sync::{mpsc, oneshot};
use vl_core::{ErrorCode, Role};

use super::extension::{Extension, SocketProtocol};
use super::hub::ToHub;
use super::web;
use crate::accounts::gate::{Credentials, Gate, Purpose};
use vl_core::Io;

/// The most a request head may be: a WebSocket upgrade is a few hundred bytes.
const MAX_HEAD: usize = 8 << 10;
const MAX_HEADERS: usize = 32;

/// What a connection opened with; each stream reads its head again.
pub(super) enum Opening {
    /// A Guest's WebSocket upgrade: the protocol of `docs/protocol.md`.
    Guest(Box<dyn Io>),
    /// An upgrade to a protocol an extension serves (Foxglove's), answered
    /// with the subprotocol it chose.
    Extension(Box<dyn Io>, Arc<dyn Extension>, SocketProtocol),
    /// A plain request, for a page.
    Page(Box<dyn Io>),
}

/// Reads a request head (at most `MAX_HEAD` bytes) from `stream`: every
/// byte read, which may run past the head.
async fn read_head(stream: &mut Box<dyn Io>) -> io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    loop {
        let n = stream.read(&mut chunk).await?;
        if n == 0 {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        head.extend_from_slice(&chunk[..n]);
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        match httparse::Request::new(&mut headers).parse(&head) {
            Ok(httparse::Status::Complete(_)) => return Ok(head),
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

/// `head` (as `read_head` gave it) parsed into `headers`.
fn parse<'h>(
    head: &'h [u8],
    headers: &'h mut [httparse::Header<'h>],
) -> io::Result<httparse::Request<'h, 'h>> {
    let mut request = httparse::Request::new(headers);
    request
        .parse(head)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?;
    Ok(request)
}

/// The value of header `name` in `request`, as text.
fn header<'a>(request: &httparse::Request<'_, 'a>, name: &str) -> Option<&'a str> {
    request
        .headers
        .iter()
        .find(|h| h.name.eq_ignore_ascii_case(name))
        .and_then(|h| std::str::from_utf8(h.value).ok())
}

/// Reads the request head from `stream` and says what it asks for.
pub(super) async fn opening(
    mut stream: Box<dyn Io>,
    extensions: &[Arc<dyn Extension>],
) -> io::Result<Opening> {
    let head = read_head(&mut stream).await?;
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let request = parse(&head, &mut headers)?;
    let upgrade = header(&request, "upgrade").is_some_and(|v| v.eq_ignore_ascii_case("websocket"));
    let chosen = header(&request, "sec-websocket-protocol").and_then(|offered| {
        extensions
            .iter()
            .find_map(|e| Some((e.clone(), e.socket_protocol(offered)?)))
    });
    let stream = Box::new(Rewind {
        head,
        read: 0,
        stream,
    });
    Ok(match (upgrade, chosen) {
        (true, Some((extension, protocol))) => Opening::Extension(stream, extension, protocol),
        (true, None) => Opening::Guest(stream),
        (false, _) => Opening::Page(stream),
    })
}

/// A plain HTTP request on a port that speaks TLS (a browser given
/// http://): answered with where it should have gone, https://, then closed.
pub(super) async fn to_https(mut stream: Box<dyn Io>) -> io::Result<()> {
    let head = read_head(&mut stream).await?;
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let request = parse(&head, &mut headers)?;
    // The host as the browser named it, if it is one (no header tricks).
    let authority = |c: char| c.is_ascii_alphanumeric() || ".-:[]".contains(c);
    let host = header(&request, "host").filter(|h| !h.is_empty() && h.chars().all(authority));
    let answer = match (host, request.path) {
        (Some(host), Some(path)) if path.starts_with('/') => format!(
            "HTTP/1.1 301 Moved Permanently\r\nLocation: https://{host}{path}\r\n\
             Content-Length: 0\r\nConnection: close\r\n\r\n"
        ),
        _ => "HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n".into(),
    };
    stream.write_all(answer.as_bytes()).await?;
    stream.shutdown().await
}

/// Who asks for a page, and what answering may need.
#[derive(Clone)]
pub(super) struct Asking {
    pub connection: u64,
    pub address: IpAddr,
    pub gate: Arc<Gate>,
    pub hub: mpsc::Sender<ToHub>,
    /// What plugs into the lab, with pages of its own (an LMS's `/lti/…`).
    pub extensions: Vec<Arc<dyn super::extension::Extension>>,
}

/// Answers the one request on `stream` (its head read again), then closes:
/// a page connection holds its place among the Host's connections only
/// as long as one answer takes.
pub(super) async fn answer(stream: Box<dyn Io>, asking: Asking) -> io::Result<()> {
    let extended: Vec<Router> = asking
        .extensions
        .iter()
        .map(|e| e.clone().routes(asking.address))
        .collect();
    let router = web::routes()
        .merge(Router::new().route("/status", get(status)))
        .with_state(asking);
    let router = extended
        .into_iter()
        .fold(router, Router::merge)
        .fallback(not_found);
    hyper::server::conn::http1::Builder::new()
        .keep_alive(false)
        .max_buf_size(MAX_HEAD)
        .serve_connection(
            hyper_util::rt::TokioIo::new(stream),
            hyper_util::service::TowerToHyperService::new(router),
        )
        .await
        .map_err(io::Error::other)
}

async fn not_found() -> Response {
    (
        StatusCode::NOT_FOUND,
        "this is a vl Host: open / in a browser to watch the lab; Guests connect here by WebSocket; GET /status shows its state\n",
    )
        .into_response()
}

/// The Host's state, to whom may see it, else why not.
async fn status(State(asking): State<Asking>, headers: HeaderMap) -> Response {
    let basic = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(basic);
    let no_store = [(header::CACHE_CONTROL, "no-store")];
    if let Err((code, why)) = admitted(basic, &asking).await {
        let status = if code == ErrorCode::TooManyAttempts {
            StatusCode::TOO_MANY_REQUESTS
        } else {
            StatusCode::UNAUTHORIZED
        };
        let challenge = [(
            header::WWW_AUTHENTICATE,
            "Basic realm=\"vl host\", charset=\"UTF-8\"",
        )];
        return (status, no_store, challenge, format!("{why}\n")).into_response();
    }
    let (tx, rx) = oneshot::channel();
    let state = match asking.hub.send(ToHub::Status(tx)).await {
        Ok(()) => rx.await.ok(),
        Err(_) => None,
    };
    match state {
        Some(state) => (no_store, axum::Json(state)).into_response(),
        None => (StatusCode::SERVICE_UNAVAILABLE, "the Host is stopping\n").into_response(),
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

/// Whether `basic`'s credentials open the status: anyone's at a lab
/// without accounts, an administrator's at one with them.
async fn admitted(
    basic: Option<(String, String)>,
    asking: &Asking,
) -> Result<(), (ErrorCode, String)> {
    if !asking.gate.has_accounts() {
        return Ok(());
    }
    let Some((user, password)) = &basic else {
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
        session: None,
        purpose: Purpose::Status,
    };
    let admitted = asking
        .gate
        .check(asking.connection, asking.address, credentials)
        .await
        .map_err(|refused| (refused.code, refused.why))?;
    match admitted.identity.is_admin() {
        true => Ok(()),
        false => Err((
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
