//! Floods from clients that hold no token, and a hundred half-sent 8 MiB
//! frames, against one Host, while an operator is welcomed and drives. The
//! attackers stand on another machine (127.0.0.2) and run in their own
//! threads and runtime; the test runs alone
//! (tests/alone.rs), so no other test's Hosts share the machine with it.

use crate::common;

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream as StdTcp;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use futures_util::SinkExt;
use serde_json::json;
use tokio_tungstenite::tungstenite::Message;

use common::peer::{Peer, memory_mb};
use common::start_host;

/// Where the attackers stand: another machine than the operator's. (One
/// address's silent sockets push out only each other; whoever shares an
/// attacker's address — a class behind one router — shares its fate.)
const ELSEWHERE: &str = "127.0.0.2:0";

/// A TCP connection to `addr` from [`ELSEWHERE`].
async fn from_elsewhere(addr: &str) -> Option<tokio::net::TcpStream> {
    let socket = tokio::net::TcpSocket::new_v4().ok()?;
    socket.bind(ELSEWHERE.parse().ok()?).ok()?;
    socket.connect(addr.parse().ok()?).await.ok()
}

/// A WebSocket to `url` from [`ELSEWHERE`].
async fn websocket_from_elsewhere(
    url: &str,
) -> Option<tokio_tungstenite::WebSocketStream<tokio::net::TcpStream>> {
    let stream = from_elsewhere(url.trim_start_matches("ws://")).await?;
    let (ws, _) = tokio_tungstenite::client_async(url, stream).await.ok()?;
    Some(ws)
}

/// Sends a WebSocket handshake by hand, then the start of a frame that
/// claims 8 MiB − 1 bytes, and stalls.
fn half_frame(addr: &str, runtime: &tokio::runtime::Runtime) -> Option<StdTcp> {
    let mut s = runtime.block_on(from_elsewhere(addr))?.into_std().ok()?;
    s.set_nonblocking(false).ok()?;
    let request = format!(
        "GET / HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    );
    s.write_all(request.as_bytes()).ok()?;
    let mut reader = BufReader::new(s.try_clone().ok()?);
    let mut line = String::new();
    while reader.read_line(&mut line).ok()? > 2 {
        line.clear();
    }
    let len: u64 = (8 << 20) - 1;
    let mut header = vec![0x81, 0xFF];
    header.extend_from_slice(&len.to_be_bytes());
    header.extend_from_slice(&[1, 2, 3, 4]);
    header.extend(std::iter::repeat_n(b'x', 64 << 10));
    let _ = s.write_all(&header);
    Some(s)
}

/// Lowers the calling thread's priority (Linux's nice is per thread). The
/// attackers stand for other machines: on this one they must still send
/// as fast as the Host lets them, but not take the CPU the Host and the
/// operator would have had on their own machines.
fn behind_the_host() {
    // SAFETY: setpriority only reads its integer arguments.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}

/// Floods from clients with no token, and a hundred half-sent 8 MiB
/// frames, while an operator is welcomed and drives.
/// The attackers: two clients pipelining tiny messages as fast as they
/// can, two sending 1 MiB of JSON again and again (both reconnecting when
/// cut off), and a hundred half-sent 8 MiB frames renewed as the Host drops
/// them — on their own threads and runtime, until `stop`.
fn attack(url: String, stop: Arc<AtomicBool>) -> Vec<std::thread::JoinHandle<()>> {
    let mut threads = Vec::new();
    {
        let (url, stop) = (url.clone(), stop.clone());
        threads.push(std::thread::spawn(move || {
            behind_the_host();
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            runtime.block_on(async move {
                let mut tasks = Vec::new();
                for _ in 0..2 {
                    let (url, stop) = (url.clone(), stop.clone());
                    tasks.push(tokio::spawn(async move {
                        while !stop.load(Ordering::Relaxed) {
                            let Some(mut ws) = websocket_from_elsewhere(&url).await else {
                                continue;
                            };
                            // Until the Host cuts it off: a full socket holds it back.
                            for i in 0u64.. {
                                if stop.load(Ordering::Relaxed) {
                                    break;
                                }
                                let tiny = if i % 2 == 0 {
                                    r#"{"type":"ping","t":1}"#
                                } else {
                                    "x"
                                };
                                if ws.feed(Message::text(tiny)).await.is_err() {
                                    break;
                                }
                                if i % 64 == 0 && ws.flush().await.is_err() {
                                    break;
                                }
                            }
                        }
                    }));
                }
                for _ in 0..2 {
                    let (url, stop) = (url.clone(), stop.clone());
                    tasks.push(tokio::spawn(async move {
                        let pad = "y".repeat((1 << 20) - 80);
                        let big = format!(
                            r#"{{"type":"hello","protocol":1,"role":"observer","pad":"{pad}"}}"#
                        );
                        while !stop.load(Ordering::Relaxed) {
                            let Some(mut ws) = websocket_from_elsewhere(&url).await else {
                                continue;
                            };
                            while !stop.load(Ordering::Relaxed) {
                                if ws.send(Message::text(big.clone())).await.is_err() {
                                    break;
                                }
                            }
                        }
                    }));
                }
                for task in tasks {
                    let _ = task.await;
                }
            });
        }));
    }
    let addr = url.trim_start_matches("ws://").to_owned();
    threads.push(std::thread::spawn(move || {
        behind_the_host();
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        // A hundred of them open at once; one the Host has closed is opened again.
        let mut held: Vec<Option<StdTcp>> = (0..100).map(|_| None).collect();
        while !stop.load(Ordering::Relaxed) {
            for slot in &mut held {
                let closed = slot.as_ref().is_none_or(|s| {
                    let _ = s.set_nonblocking(true);
                    let mut byte = [0u8; 1];
                    matches!(std::io::Read::read(&mut &*s, &mut byte), Ok(0))
                        || matches!(std::io::Read::read(&mut &*s, &mut byte), Err(e) if e.kind() != std::io::ErrorKind::WouldBlock)
                });
                if closed {
                    *slot = half_frame(&addr, &runtime);
                }
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }));
    threads
}

/// The operator's round-trip p99 under floods, ms: the Host's 20 ms
/// feedback period (a command is answered before the next feedback is
/// due). Half of it held on quieter days; this VM has since measured
/// 7–13 ms with the floods, old and new builds alike, where a Host the
/// floods held up takes tens of ms.
const P99_LIMIT_MS: f64 = 20.0;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn floods_and_half_frames_do_not_slow_the_operator() {
    let _alone = crate::alone().await;
    let (host, url) = start_host(&["--camera", "sim"]);
    let pid = host.0.id();
    let stop = Arc::new(AtomicBool::new(false));
    let attackers = attack(url.clone(), stop.clone());
    tokio::time::sleep(Duration::from_secs(2)).await;

    // A newcomer's welcome, as its best of three: one slow welcome is this
    // machine pausing; a Host the floods hold up is slow every time.
    let mut welcome_ms = f64::INFINITY;
    for _ in 0..3 {
        let started = Instant::now();
        let mut newcomer = Peer::connect(&url).await;
        newcomer.hello("observer").await;
        welcome_ms = welcome_ms.min(started.elapsed().as_secs_f64() * 1e3);
        newcomer.send(json!({"type": "bye"})).await;
        if welcome_ms < 100.0 {
            break;
        }
    }
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    op.start("teleoperation").await;
    // The operator's round trips, while it drives, 500 at a time. A round
    // whose p99 is over the limit is measured again, up to three rounds:
    // this VM pauses now and then for a few ms, which no Host can help; a
    // Host the floods slow is slow in every round.
    //
    // The limit is the 20 ms feedback period: within it, the operator's
    // commands and pings are answered before the next feedback whatever
    // the floods do. On an idle Host a debug build answers in
    // 0.3 ms (p99); under these floods in 1–13 ms, the Host's own work of
    // reading and refusing a megabyte from a stranger, unoptimised, on the
    // same two cores; a Host the floods held up would take tens of ms.
    let mut event = 0u64;
    let mut rounds = Vec::new();
    for _ in 0..3 {
        let mut rtts = Vec::new();
        for _ in 0..500 {
            let t = Instant::now();
            op.send(json!({"type": "ping", "t": 0.0})).await;
            op.expect("pong").await;
            rtts.push(t.elapsed().as_secs_f64() * 1e3);
            event += 1;
            op.command(event, json!({"v": 50.0, "w": 0.5})).await;
        }
        rtts.sort_by(f64::total_cmp);
        rounds.push((rtts[rtts.len() / 2], rtts[rtts.len() * 99 / 100]));
        if rounds.last().is_some_and(|&(_, p99)| p99 < P99_LIMIT_MS) {
            break;
        }
    }
    let (p50, p99) = *rounds.last().expect("one round at least");
    let (rss, peak) = memory_mb(pid);
    stop.store(true, Ordering::Relaxed);
    for a in attackers {
        let _ = a.join();
    }
    println!(
        "welcomed in {welcome_ms:.1} ms; operator round trip p50 {p50:.2} ms, p99 {p99:.2} ms \
         ({} round{} of 500: {rounds:.2?}); Host memory {rss:.0} MB resident, {peak:.0} MB peak",
        rounds.len(),
        if rounds.len() == 1 { "" } else { "s" }
    );
    assert!(welcome_ms < 100.0, "welcomed after {welcome_ms:.1} ms");
    assert!(p99 < P99_LIMIT_MS, "round trip p99 {p99:.2} ms");
    assert!(peak < 256.0, "the Host grew to {peak:.0} MB");
}

/// `path` ([{x_mm, y_mm}…]) with points added along each leg until it
/// has `n`.
fn densified(path: &[serde_json::Value], n: usize) -> Vec<serde_json::Value> {
    let points: Vec<(f64, f64)> = path
        .iter()
        .map(|p| (p["x_mm"].as_f64().unwrap(), p["y_mm"].as_f64().unwrap()))
        .collect();
    let per_leg = n.div_ceil(points.len() - 1);
    let mut out = Vec::with_capacity(n);
    for leg in points.windows(2) {
        for k in 0..per_leg {
            let t = k as f64 / per_leg as f64;
            let (x, y) = (
                leg[0].0 + t * (leg[1].0 - leg[0].0),
                leg[0].1 + t * (leg[1].1 - leg[0].1),
            );
            out.push(json!({"x_mm": x, "y_mm": y}));
        }
    }
    out.truncate(n - 1);
    let last = points[points.len() - 1];
    out.push(json!({"x_mm": last.0, "y_mm": last.1}));
    out
}

/// How long each of `n` newcomers waits from its hello to its welcome, ms.
async fn welcome_times(url: &str, n: usize) -> Vec<f64> {
    let mut times = Vec::new();
    for _ in 0..n {
        let mut peer = Peer::connect(url).await;
        let asked = Instant::now();
        peer.send(json!({"type": "hello", "protocol": 1, "role": "observer"}))
            .await;
        peer.expect("welcome").await;
        times.push(asked.elapsed().as_secs_f64() * 1e3);
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    times
}

/// Newcomers are welcomed while the definitions flood in: nine in ten
/// within 150 ms (a debug build's figures, taking every one: 20 and 204 ms
/// here), none beyond a second and a half. One slow welcome is this
/// machine pausing, not the Host: the percentile judges.
fn welcomed_promptly(mut welcomes: Vec<f64>) {
    welcomes.sort_by(f64::total_cmp);
    let p90 = welcomes[welcomes.len() * 9 / 10 - 1];
    let slowest = welcomes[welcomes.len() - 1];
    assert!(
        p90 < 150.0,
        "one newcomer in ten waited {p90:.1} ms or more"
    );
    assert!(slowest < 1500.0, "a newcomer waited {slowest:.1} ms");
}

/// An operator defines a 10,000-point path 22 times in 5 s while twenty
/// watch (issue 43, item 15): two are taken at once, then one every five
/// seconds, the rest refused saying when to try again; newcomers are
/// welcomed and the hub answers meanwhile.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_long_definitions_costs_the_others_nothing() {
    let _alone = crate::alone().await;
    let (_host, url) = start_host(&[]);
    let mut operator = Peer::connect(&url).await;
    operator.hello("operator").await;
    operator
        .send(json!({"type": "mount", "experiment": "navigation"}))
        .await;
    operator.expect("mounted").await;
    operator
        .send(json!({"type": "plan", "goal": {"x_mm": 400.0, "y_mm": 300.0}}))
        .await;
    let planned = operator.expect("planned").await;
    let path = densified(planned["path"].as_array().unwrap(), 10_000);
    let definition = json!({"type": "define", "path": path}).to_string();
    // Twenty watchers, reading all they are sent: each definition taken
    // goes to every one of them.
    let mut watchers = Vec::new();
    for _ in 0..20 {
        let mut watcher = Peer::connect(&url).await;
        watcher.hello("observer").await;
        watchers.push(tokio::spawn(async move {
            while watcher.next_any().await.is_some() {}
        }));
    }
    let quiet = welcome_times(&url, 5).await;
    // An observer asks the hub something every 50 ms: how long it answers.
    let mut asking = Peer::connect(&url).await;
    asking.hello("observer").await;
    let answers = tokio::spawn(async move {
        let mut times = Vec::new();
        let began = Instant::now();
        while began.elapsed() < Duration::from_secs(6) {
            let asked = Instant::now();
            asking.send(json!({"type": "leave_queue"})).await;
            asking.expect("queue").await;
            times.push(asked.elapsed().as_secs_f64() * 1e3);
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        times.sort_by(f64::total_cmp);
        times
    });
    let flood = tokio::spawn(async move {
        let (mut defined, mut refused) = (0, 0);
        for _ in 0..22 {
            operator.send_text(&definition).await;
            tokio::time::sleep(Duration::from_millis(227)).await;
            while let Some(answer) = operator
                .next_of_any(&["defined", "error"], Duration::from_millis(1))
                .await
            {
                if answer["type"] == "defined" {
                    defined += 1;
                } else {
                    refused += 1;
                }
            }
        }
        // What is still on its way: the connection reads a client within
        // its byte rate, so some definitions are answered late.
        while defined + refused < 22 {
            let Some(answer) = operator
                .next_of_any(&["defined", "error"], Duration::from_secs(10))
                .await
            else {
                break;
            };
            if answer["type"] == "defined" {
                defined += 1;
            } else {
                refused += 1;
            }
        }
        (defined, refused)
    });
    let flooded = welcome_times(&url, 20).await;
    let (defined, refused) = flood.await.unwrap();
    let answered = answers.await.unwrap();
    let (p90, slowest) = (
        answered[answered.len() * 9 / 10],
        answered[answered.len() - 1],
    );
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    println!(
        "welcomes: quiet at most {:.1} ms, flooded at most {:.1} ms; the hub answered {} asks, 90 % within {p90:.1} ms, all within {slowest:.1} ms; {defined} definitions taken, {refused} refused",
        max(&quiet),
        max(&flooded),
        answered.len()
    );
    // Two at once, then one every five seconds or so.
    assert!((2..=5).contains(&defined), "{defined} taken");
    assert_eq!(defined + refused, 22);
    welcomed_promptly(flooded);
    // The hub answers while the definitions flood it: nine in ten asks
    // within 300 ms (a debug build; 20 ms when quiet), and none waits a
    // second and a half (a hub that took the definitions' work on itself
    // would hold every ask for as long as each of them takes). One slow
    // answer is this machine pausing, not the Host: the percentile judges.
    assert!(
        p90 < 300.0,
        "the hub took {p90:.1} ms to answer one ask in ten"
    );
    assert!(slowest < 1500.0, "the hub took {slowest:.1} ms to answer");
    for watcher in watchers {
        watcher.abort();
    }
}
