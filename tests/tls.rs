//! WebSocket over TLS: a Host with a self-signed certificate prints its
//! address with the fingerprint to pin; the Guest runs a whole experiment
//! through it, refuses a certificate that is not the pinned one, and an
//! outside client (Python's websockets and ssl) is welcomed; plain ws:// is
//! not spoken on that port, and plain http:// is sent on to https://; a
//! restarted Host keeps its self-signed certificate, so its pin.

use std::process::Command;
use std::time::Duration;

use crate::common::{self, start_host};

/// A Host speaking only TLS: its wss:// address with `#pin=`.
fn tls_host() -> (common::VlProcess, String) {
    let (host, url) = start_host(&["--tls-self-signed"]);
    assert!(
        url.starts_with("wss://127.0.0.1:") && url.contains("/#pin="),
        "{url}"
    );
    (host, url)
}

#[test]
fn a_guest_runs_through_tls_with_the_pinned_certificate_only() {
    let (_host, url) = tls_host();
    let run = |url: &str| {
        common::vl_command()
            .args(["guest", "--headless", "--connect", url, "--timeout", "60"])
            .output()
            .unwrap()
    };
    let done = run(&url);
    assert!(done.status.success(), "{}", common::stderr(&done));
    let (address, pin) = url.split_once("#pin=").unwrap();
    let other = format!("{address}#pin={}", "0".repeat(64));
    let refused = run(&other);
    assert!(!refused.status.success());
    let err = common::stderr(&refused);
    assert!(
        err.contains(&format!("the Host's certificate is {pin}, not the pinned")),
        "{err}"
    );
    // Unpinned, a self-signed certificate is no public authority's.
    let unpinned = run(address);
    assert!(!unpinned.status.success());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plain_websocket_is_not_spoken_where_tls_is() {
    let (_host, url) = tls_host();
    let plain = url.replace("wss://", "ws://");
    let plain = plain.split('#').next().unwrap();
    let tried = tokio::time::timeout(
        Duration::from_secs(10),
        tokio_tungstenite::connect_async(plain),
    )
    .await
    .expect("an answer within the handshake timeout");
    assert!(tried.is_err(), "a plain handshake was accepted");
}

#[test]
fn plain_http_on_the_tls_port_is_sent_to_https() {
    use std::io::{Read, Write};
    let (_host, url) = tls_host();
    let authority = url
        .trim_start_matches("wss://")
        .split('/')
        .next()
        .unwrap()
        .to_owned();
    let ask = |request: String| {
        let mut socket = std::net::TcpStream::connect(&authority).unwrap();
        socket
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        socket.write_all(request.as_bytes()).unwrap();
        let mut answer = String::new();
        socket.read_to_string(&mut answer).unwrap();
        answer
    };
    // A browser given http://…/status is sent to the same place over TLS.
    let answer = ask(format!(
        "GET /status?x=1 HTTP/1.1\r\nHost: {authority}\r\nUser-Agent: test\r\n\r\n"
    ));
    assert!(answer.starts_with("HTTP/1.1 301"), "{answer}");
    assert!(
        answer.contains(&format!("Location: https://{authority}/status?x=1\r\n")),
        "{answer}"
    );
    // A host that is no host name is not echoed into the answer.
    let answer = ask("GET / HTTP/1.1\r\nHost: evil\"<x>\r\n\r\n".into());
    assert!(answer.starts_with("HTTP/1.1 400"), "{answer}");
    assert!(!answer.contains("evil"), "{answer}");
}

#[test]
fn an_outside_client_is_welcomed_over_tls() {
    // CI installs Debian's python3-websockets.
    let Some(python) = common::python_with("websockets") else {
        return;
    };
    let (_host, url) = tls_host();
    let (address, pin) = url.split_once("/#pin=").unwrap();
    let port = address.rsplit(':').next().unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/tls/client.py");
    let out = Command::new(python)
        .args([script, port, pin])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    assert!(
        common::stdout(&out).starts_with("welcome "),
        "{}",
        common::stdout(&out)
    );
}

/// `vl host --tls-self-signed` on `port`, keeping its certificate under
/// `data` (as vl's data directory): its wss:// address.
fn kept_tls_host(data: &std::path::Path, port: u16, extra: &[&str]) -> (common::VlProcess, String) {
    use std::io::BufRead;
    let mut command = common::vl_command();
    command
        .env("XDG_DATA_HOME", data)
        .args(["host", "--robot", "sim", "--no-record", "--tls-self-signed"])
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(extra)
        .stdout(std::process::Stdio::piped());
    let mut child = command.spawn().unwrap();
    let stdout = child.stdout.take().unwrap();
    let host = common::VlProcess(child);
    let mut line = String::new();
    std::io::BufReader::new(stdout)
        .read_line(&mut line)
        .unwrap();
    let url = line
        .trim()
        .strip_prefix("vl host listening on ")
        .unwrap_or_else(|| panic!("{line:?}"))
        .to_owned();
    (host, url)
}

/// The next welcome `connection` gets, within `wait`.
async fn welcomed(connection: &mut vl_client::Connection, wait: Duration) -> bool {
    let deadline = tokio::time::Instant::now() + wait;
    while let Ok(Some(incoming)) = tokio::time::timeout_at(deadline, connection.recv()).await {
        if let vl_client::Incoming::Message(m) = incoming
            && matches!(*m, vl_core::HostMessage::Welcome { .. })
        {
            return true;
        }
    }
    false
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_self_signed_host_keeps_its_pin_and_a_pinned_guest_comes_back() {
    let data = common::scratch("tls-kept");
    let port = common::free_port();
    let (host, url) = kept_tls_host(&data, port, &[]);
    assert!(url.contains("#pin="), "{url}");
    let mut guest = vl_client::open(&url).unwrap();
    guest
        .outgoing
        .send(vl_client::Login::default().hello(vl_core::Role::Observer))
        .unwrap();
    assert!(
        welcomed(&mut guest, Duration::from_secs(20)).await,
        "no welcome"
    );
    // The Host stops (as a machine restarting would) and starts again.
    drop(host);
    let (host, again) = kept_tls_host(&data, port, &[]);
    assert_eq!(again, url, "a restart changed the address Guests pin");
    assert!(
        welcomed(&mut guest, Duration::from_secs(30)).await,
        "the pinned Guest did not come back"
    );
    drop(host);
    // Renewed on request: a new certificate, a new pin.
    let (_host, renewed) = kept_tls_host(&data, port, &["--tls-renew"]);
    assert_ne!(renewed, url);
    assert!(data.join("vl/tls/self-signed.pem").exists());
}
