//! Asking a Host how it is (`vl host status`): one `GET /status` on its
//! WebSocket port, over TLS when the address is `wss://` (pinned as a
//! Guest pins it), with an administrator's account as HTTP Basic
//! credentials at a lab with accounts.

use std::time::Duration;

use base64::Engine;
use thiserror::Error;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use vl_core::HostStatus;

use crate::dial::Target;
use crate::login::Login;

/// The whole answer must come within this.
const ANSWER_WAIT: Duration = Duration::from_secs(10);
/// No status is larger than this.
const MAX_ANSWER: u64 = 1 << 20;

#[derive(Debug, Error)]
pub enum StatusError {
    #[error("{url}: {why}")]
    Address { url: String, why: String },
    #[error("cannot reach the Host: {0}")]
    Connect(std::io::Error),
    #[error("the Host did not answer within {0:?}")]
    Silent(Duration),
    #[error("the Host refused: {0}")]
    Refused(String),
    #[error("the Host's answer is not a status: {0}")]
    Answer(String),
}

/// The status of the Host at `url`, asked as `login` (an account; a token
/// opens no status).
pub async fn host_status(url: &str, login: &Login) -> Result<HostStatus, StatusError> {
    let target = Target::of(url).map_err(|why| StatusError::Address {
        url: url.to_owned(),
        why,
    })?;
    tokio::time::timeout(ANSWER_WAIT, ask(&target, login))
        .await
        .map_err(|_| StatusError::Silent(ANSWER_WAIT))?
}

async fn ask(target: &Target, login: &Login) -> Result<HostStatus, StatusError> {
    let mut stream = target.dial().await.map_err(StatusError::Connect)?;
    let authorization = match (&login.user, &login.password) {
        (Some(user), Some(password)) => format!(
            "Authorization: Basic {}\r\n",
            base64::engine::general_purpose::STANDARD.encode(format!("{user}:{password}"))
        ),
        _ => String::new(),
    };
    let request = format!(
        "GET /status HTTP/1.1\r\nHost: {}\r\n{authorization}Connection: close\r\n\r\n",
        target.authority()
    );
    stream
        .write_all(request.as_bytes())
        .await
        .map_err(StatusError::Connect)?;
    let mut answer = Vec::new();
    stream
        .take(MAX_ANSWER)
        .read_to_end(&mut answer)
        .await
        .map_err(StatusError::Connect)?;
    let mut headers = [httparse::EMPTY_HEADER; 32];
    let mut response = httparse::Response::new(&mut headers);
    let body_at = match response.parse(&answer) {
        Ok(httparse::Status::Complete(at)) => at,
        _ => {
            let hint = if target.url.starts_with("ws://") {
                " (a Host with TLS on is reached at wss://)"
            } else {
                ""
            };
            return Err(StatusError::Answer(format!("no HTTP response{hint}")));
        }
    };
    let body = String::from_utf8_lossy(&answer[body_at..]);
    match response.code {
        Some(200) => serde_json::from_str(&body).map_err(|e| StatusError::Answer(e.to_string())),
        _ => Err(StatusError::Refused(body.trim().to_owned())),
    }
}
