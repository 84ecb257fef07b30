//! WebSocket over TLS: a Host with a self-signed certificate prints its
//! address with the fingerprint to pin; the Guest runs a whole experiment
//! through it, refuses a certificate that is not the pinned one, and an
//! outside client (Python's websockets and ssl) is welcomed; plain ws:// is
//! not spoken on that port.

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
