//! The Media relay (`vl media`) measured from outside: a client sends
//! timestamped messages through it to an echo server and times the round
//! trips. The relay seeds connection k's links `seed + 2k` and `seed + 2k + 1`,
//! so the same model run in virtual time on the same send times says what
//! each round trip should have been; the relay must reproduce that on real
//! sockets, on top of its own (zero-delay) cost.

mod common;

use std::time::{Duration, Instant};

use common::{VlProcess, scratch, start_vl};
use futures_util::{SinkExt, StreamExt};
use tokio::net::TcpListener;
use tokio_tungstenite::tungstenite::Message;
use vl_core::Named;
use vl_sim::{Delivery, LinkModel, MessageLink, Profile};

/// The tests here time the relay, and one runs a whole lab: one at a
/// time, so none measures another's load.
static ONE_AT_A_TIME: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

const CONNECTIONS: u64 = 8;
const PINGS: usize = 25;
const INTERVAL: Duration = Duration::from_millis(100);
const SEED: u64 = 11;

/// An echo server on a free port: every text message goes straight back.
async fn echo() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("ws://{}", listener.local_addr().unwrap());
    tokio::spawn(async move {
        while let Ok((stream, _)) = listener.accept().await {
            let _ = stream.set_nodelay(true);
            tokio::spawn(async move {
                let Ok(mut ws) = tokio_tungstenite::accept_async(stream).await else {
                    return;
                };
                while let Some(Ok(m)) = ws.next().await {
                    if m.is_text() && ws.send(m).await.is_err() {
                        return;
                    }
                }
            });
        }
    });
    url
}

/// Starts `vl media` in front of `upstream` with `profile`; returns its URL.
fn media(upstream: &str, profile: &str) -> (VlProcess, String) {
    let (process, rest) = start_vl(
        &[
            "media",
            "--listen",
            "127.0.0.1:0",
            "--upstream",
            upstream,
            "--profile",
            profile,
            "--seed",
            &SEED.to_string(),
        ],
        "vl media listening on ",
    );
    let url = rest.split(' ').next().unwrap().to_owned();
    (process, url)
}

/// Each connection's (send time ms since the first send, round trip ms).
async fn round_trips(url: &str) -> Vec<Vec<(f64, f64)>> {
    let mut sockets = Vec::new();
    // One at a time, so the relay numbers them in this order.
    for _ in 0..CONNECTIONS {
        let (ws, _) = tokio_tungstenite::connect_async(url)
            .await
            .expect("connects");
        sockets.push(ws);
    }
    let epoch = Instant::now();
    // Staggered, one message at a time: the link is timed, not a burst.
    let runs = (0u32..).zip(sockets).map(|(k, ws)| async move {
        let offset = INTERVAL * k / CONNECTIONS as u32;
        let (mut sink, mut source) = ws.split();
        let sender = async {
            let mut sent = Vec::new();
            for i in 0..PINGS {
                tokio::time::sleep_until((epoch + offset + INTERVAL * i as u32).into()).await;
                sent.push(epoch.elapsed().as_secs_f64() * 1e3);
                sink.send(Message::text(format!("{i:0>64}"))).await.unwrap();
            }
            sent
        };
        let receiver = async {
            let mut back = Vec::new();
            while back.len() < PINGS {
                match source.next().await {
                    Some(Ok(m)) if m.is_text() => back.push(epoch.elapsed().as_secs_f64() * 1e3),
                    Some(Ok(_)) => {}
                    other => panic!("the relay ended the connection: {other:?}"),
                }
            }
            back
        };
        let (sent, back) = tokio::join!(sender, receiver);
        sent.iter()
            .zip(&back)
            .map(|(s, b)| (*s, b - s))
            .collect::<Vec<_>>()
    });
    futures_util::future::join_all(runs).await
}

/// What the model says each round trip is, on the same send times.
fn modelled(model: &LinkModel, measured: &[Vec<(f64, f64)>]) -> Vec<f64> {
    let mut all = Vec::new();
    for (k, pings) in measured.iter().enumerate() {
        let k = k as u64;
        let mut up = MessageLink::new(model.clone(), SEED + 2 * k);
        let mut down = MessageLink::new(model.clone(), SEED + 2 * k + 1);
        for &(sent, _) in pings {
            let Delivery::At(there) = up.send(sent, 64) else {
                panic!("no disconnects")
            };
            let Delivery::At(back) = down.send(there, 64) else {
                panic!("no disconnects")
            };
            all.push(back - sent);
        }
    }
    all
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

fn zero_profile(dir: &std::path::Path) -> String {
    let zero = LinkModel {
        delay_ms: 0.0,
        jitter_ms: 0.0,
        ..LinkModel::profile(Profile::Lan)
    };
    let file = dir.join("zero.json");
    std::fs::write(&file, serde_json::to_string(&zero).unwrap()).unwrap();
    file.to_str().unwrap().to_owned()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_relay_gives_real_messages_each_profile_s_delay_and_jitter() {
    let _alone = ONE_AT_A_TIME.lock().await;
    let upstream = echo().await;
    let dir = scratch("media-profiles");
    let (_zero, zero_url) = media(&upstream, &zero_profile(&dir));
    let own: Vec<f64> = round_trips(&zero_url)
        .await
        .into_iter()
        .flatten()
        .map(|(_, rtt)| rtt)
        .collect();
    let (own_mean, own_sd) = mean_sd(&own);
    println!("the relay's own round trip: mean {own_mean:.3} ms, sd {own_sd:.3} ms");
    println!(
        "{:<18} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "profile", "nominal", "model", "measured", "nominal sd", "model sd", "meas. sd"
    );
    for &profile in Profile::ALL {
        let model = LinkModel::profile(profile);
        let (_relay, url) = media(&upstream, profile.id());
        let measured = round_trips(&url).await;
        let expected = modelled(&model, &measured);
        let rtts: Vec<f64> = measured.iter().flatten().map(|&(_, rtt)| rtt).collect();
        let (m_mean, m_sd) = mean_sd(&rtts);
        let (e_mean, e_sd) = mean_sd(&expected);
        // What the relay added by its model: its own cost taken away.
        let added_mean = m_mean - own_mean;
        let added_sd = (m_sd * m_sd - own_sd * own_sd).max(0.0).sqrt();
        println!(
            "{:<18} {:>10.2} {:>10.2} {:>10.2} {:>10.3} {:>10.3} {:>10.3}",
            profile.id(),
            2.0 * model.expected_delay(),
            e_mean,
            added_mean,
            2f64.sqrt() * model.expected_jitter(),
            e_sd,
            added_sd
        );
        // 5 %, or the relay's own spread where that is larger: on a LAN's
        // 1 ms the scheduler's noise is larger than 5 % (see `vl media bench`).
        let within = |got: f64, want: f64| (got - want).abs() <= (0.05 * want).max(own_sd);
        assert!(
            within(added_mean, e_mean),
            "{profile}: round trip {added_mean:.3} ms against the model's {e_mean:.3}"
        );
        assert!(
            within(added_sd, e_sd),
            "{profile}: jitter {added_sd:.3} ms against the model's {e_sd:.3}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_disconnect_closes_connections_and_refuses_new_ones_until_it_ends() {
    let _alone = ONE_AT_A_TIME.lock().await;
    let upstream = echo().await;
    let dir = scratch("media-disconnect");
    let file = dir.join("outage.json");
    let model = LinkModel {
        disconnects: vec![(1500.0, 3000.0)],
        ..LinkModel::profile(Profile::Lan)
    };
    std::fs::write(&file, serde_json::to_string(&model).unwrap()).unwrap();
    let started = Instant::now();
    let (_relay, url) = media(&upstream, file.to_str().unwrap());
    let (mut ws, _) = tokio_tungstenite::connect_async(&url)
        .await
        .expect("connects before the outage");
    ws.send(Message::text("hello")).await.unwrap();
    assert!(matches!(ws.next().await, Some(Ok(m)) if m.is_text()));
    // The outage closes the connection without a word.
    let closed = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match ws.next().await {
                Some(Ok(m)) if m.is_text() => {}
                _ => return started.elapsed(),
            }
        }
    })
    .await
    .expect("the connection closes in the outage");
    assert!(
        closed >= Duration::from_millis(1400),
        "closed after {closed:?}"
    );
    let during = tokio_tungstenite::connect_async(&url).await;
    assert!(during.is_err(), "a connection during the outage is refused");
    tokio::time::sleep_until((started + Duration::from_millis(3300)).into()).await;
    let (mut ws, _) = tokio_tungstenite::connect_async(&url)
        .await
        .expect("connects after the outage");
    ws.send(Message::text("back")).await.unwrap();
    assert!(matches!(ws.next().await, Some(Ok(m)) if m.is_text()));
}

#[test]
fn bad_profiles_and_upstreams_are_named() {
    common::refused(
        &["media", "--profile", "dialup", "--listen", "127.0.0.1:0"],
        "'dialup' is neither a link profile",
    );
    common::refused(
        &[
            "media",
            "--profile",
            "lan",
            "--listen",
            "127.0.0.1:0",
            "--upstream",
            "http://x",
        ],
        "is not ws://",
    );
}

#[test]
fn a_demo_behind_a_link_feels_its_delay() {
    let _alone = ONE_AT_A_TIME.blocking_lock();
    let report = common::vl_json(&["demo", "--headless", "--json", "--link", "intercontinental"]);
    assert_eq!(report["reached_goal"], true, "{report}");
    let rtt = report["round_trip_ms"]["p50"].as_f64().unwrap();
    assert!(
        (140.0..200.0).contains(&rtt),
        "a 150 ms link, round trip {rtt} ms"
    );
}
