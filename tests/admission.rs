//! Admission that favours people: another machine (127.0.0.2, here) opens
//! 200 bare TCP connections a second against both the Host and `vl media`
//! and never says a word, while an operator far away — a geo-satellite
//! link, 560 ms round trip, through the relay — connects and is welcomed;
//! and observers that never read hold the relay to a bounded memory. The
//! three-minute soak is `bench/admission.sh`; this is its short form.

use crate::common;

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use serde_json::json;
use tokio::net::TcpSocket;

use common::peer::{Peer, memory_mb};
use common::{start_host, start_media};

/// Opens `per_s` bare connections a second from 127.0.0.2 to `target`,
/// holding each until it is closed by the other end or the flood ends.
fn bare_flood(target: SocketAddr, per_s: u64, stop: Arc<AtomicBool>, opened: Arc<AtomicU64>) {
    std::thread::spawn(move || {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        runtime.block_on(async move {
            let mut held = Vec::new();
            let mut tick = tokio::time::interval(Duration::from_micros(1_000_000 / per_s));
            while !stop.load(Ordering::Relaxed) {
                tick.tick().await;
                let Ok(socket) = TcpSocket::new_v4() else {
                    continue;
                };
                if socket.bind("127.0.0.2:0".parse().unwrap()).is_err() {
                    continue;
                }
                if let Ok(Ok(stream)) =
                    tokio::time::timeout(Duration::from_millis(200), socket.connect(target)).await
                {
                    opened.fetch_add(1, Ordering::Relaxed);
                    held.push(stream);
                }
                // Keep the newest few hundred open: what a flood holds at once.
                if held.len() > 500 {
                    held.drain(..100);
                }
            }
        });
    });
}

fn addr(url: &str) -> SocketAddr {
    url.trim_start_matches("ws://").parse().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bare_connects_from_elsewhere_never_keep_a_far_operator_out() {
    let (_host, host_url) = start_host(&["--camera", "sim"]);
    let (media, media_url) = start_media(&host_url, "geo-satellite", &[]);
    let stop = Arc::new(AtomicBool::new(false));
    let opened = Arc::new(AtomicU64::new(0));
    bare_flood(addr(&host_url), 200, stop.clone(), opened.clone());
    bare_flood(addr(&media_url), 200, stop.clone(), opened.clone());
    tokio::time::sleep(Duration::from_secs(2)).await;

    // The operator, 560 ms away through the relay, tries as a Guest does.
    let began = Instant::now();
    let mut welcomed = None;
    for _ in 0..5 {
        let Ok(mut op) = Peer::try_connect(&media_url).await else {
            continue;
        };
        op.send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
            .await;
        if let Some(w) = op.next_of("welcome", Duration::from_secs(5)).await {
            welcomed = Some((w, op));
            break;
        }
    }
    let took = began.elapsed();
    println!(
        "{} bare connections opened; the far operator welcomed after {took:?}",
        opened.load(Ordering::Relaxed)
    );
    let (welcome, _op) = welcomed.expect("the far operator is welcomed");
    assert_eq!(welcome["role"], "operator");
    assert!(took < Duration::from_secs(6), "{took:?}");
    stop.store(true, Ordering::Relaxed);

    // Sixteen observers through the relay that never read a frame.
    let before = memory_mb(media.0.id()).0;
    let mut silent = Vec::new();
    for _ in 0..16 {
        let mut o = Peer::connect(&media_url).await;
        o.send(json!({"type": "hello", "protocol": 1, "role": "observer"}))
            .await;
        silent.push(o);
    }
    let soak_s: u64 = std::env::var("ADMISSION_SOAK_S")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20);
    let mut peak: f64 = 0.0;
    for _ in 0..soak_s {
        tokio::time::sleep(Duration::from_secs(1)).await;
        peak = peak.max(memory_mb(media.0.id()).0);
    }
    drop(silent);
    tokio::time::sleep(Duration::from_secs(2)).await;
    let after = memory_mb(media.0.id()).0;
    println!(
        "the relay: {before:.0} MB before, {peak:.0} MB at most with 16 observers not reading for {soak_s} s, {after:.0} MB once they left"
    );
    assert!(peak < 100.0, "{peak:.0} MB");
}

/// A Foxglove client offering its subprotocol: the server's first word.
async fn foxglove_server_info(url: &str) -> Option<serde_json::Value> {
    use futures_util::StreamExt;
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let mut request = url.into_client_request().ok()?;
    request.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        "foxglove.websocket.v1".parse().ok()?,
    );
    let (mut ws, _) = tokio_tungstenite::connect_async(request).await.ok()?;
    let first = tokio::time::timeout(Duration::from_secs(10), ws.next())
        .await
        .ok()??
        .ok()?;
    serde_json::from_str(first.to_text().ok()?).ok()
}

/// A class behind one router — thirty pages and thirty Foxglove clients,
/// one address, all at once — is let in whole: no one is pushed out by a
/// classmate (issue 43, item 8).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_class_behind_one_router_gets_in_at_once() {
    let (_host, url) = start_host(&["--camera", "sim"]);
    let guests = (0..30).map(|_| {
        let url = url.clone();
        async move {
            let mut peer = Peer::try_connect(&url).await.ok()?;
            peer.send(json!({"type": "hello", "protocol": 1, "role": "observer"}))
                .await;
            let welcome = peer.next_of("welcome", Duration::from_secs(10)).await?;
            Some((welcome, peer))
        }
    });
    let foxglove = (0..30).map(|_| foxglove_server_info(&url));
    let (guests, foxglove) = tokio::join!(
        futures_util::future::join_all(guests),
        futures_util::future::join_all(foxglove)
    );
    let welcomed = guests.iter().filter(|g| g.is_some()).count();
    let informed = foxglove
        .iter()
        .filter(|f| f.as_ref().is_some_and(|v| v["op"] == "serverInfo"))
        .count();
    assert_eq!((welcomed, informed), (30, 30));
}

/// More handshakes at once than a Host lets wait (64 from one address):
/// those pushed out are told so, HTTP 503 with `Retry-After`, and a page
/// that tries again itself, never a connection cut with no word (issue
/// 55, item 10); those still waiting are served.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_host_with_no_room_says_503_and_when_to_try_again() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let (_host, url) = start_host(&["--camera", "sim"]);
    let target = addr(&url);
    // Each sends all of a request's head but its end, and waits.
    let mut told = Vec::new();
    for _ in 0..100 {
        let mut socket = tokio::net::TcpStream::connect(target).await.unwrap();
        socket
            .write_all(b"GET / HTTP/1.1\r\nHost: lab\r\n")
            .await
            .unwrap();
        told.push(tokio::spawn(async move {
            let mut heard = Vec::new();
            let _ =
                tokio::time::timeout(Duration::from_secs(3), socket.read_to_end(&mut heard)).await;
            String::from_utf8_lossy(&heard).into_owned()
        }));
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let mut busy = 0;
    let mut waiting = 0;
    for heard in told {
        let heard = heard.await.unwrap();
        if heard.starts_with("HTTP/1.1 503 ") {
            assert!(heard.contains("\r\nRetry-After: 2\r\n"), "{heard}");
            assert!(heard.contains("http-equiv=\"refresh\""), "{heard}");
            busy += 1;
        } else if heard.is_empty() {
            waiting += 1;
        }
    }
    println!("of 100 handshakes at once: {busy} told 503, {waiting} still waiting after 3 s");
    assert_eq!(busy, 36, "the 36 pushed out are told 503");
    assert_eq!(waiting, 64, "64 from one address may wait");
}
