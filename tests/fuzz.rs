//! A seeded socket fuzzer against `vl host`: several clients at once send
//! valid messages with hostile values, broken JSON, unknown types, bytes,
//! oversized text, out-of-order actions, and hang up at random. Afterwards
//! the Host must still be up, small, and serve an operator normally.
//!
//! `FUZZ_MESSAGES` (default 3,000) and `FUZZ_SEED` (default 1) set the run;
//! `bench/fuzz.sh` runs it for as long as asked.

use crate::common;

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::connect_async;
use tokio_tungstenite::tungstenite::Message;
use vl_core::{GuestMessage, Wire};

use common::peer::{Peer, assert_finite_feedback, memory_mb};
use common::start_host;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len() as u64) as usize]
    }

    /// A number a careless or hostile client might send.
    fn number(&mut self) -> Value {
        match self.below(10) {
            0 => json!(1e308),
            1 => json!(-1e308),
            2 => json!(5e-324),
            3 => json!(0),
            4 => json!(-0.0),
            5 => Value::String("NaN".into()),
            6 => json!(u64::MAX),
            7 => json!(i64::MIN),
            _ => json!((self.next() % 4000) as f64 - 2000.0),
        }
    }

    fn point(&mut self) -> Value {
        json!({"x_mm": self.number(), "y_mm": self.number()})
    }
}

/// One message: text (usually JSON) or bytes.
fn message(rng: &mut Rng) -> Message {
    let text = match rng.below(20) {
        0 => {
            return Message::binary(
                (0..rng.below(2000))
                    .map(|_| rng.next() as u8)
                    .collect::<Vec<u8>>(),
            );
        }
        1 => "x".repeat((1 << 20) + 10), // over the limit
        2 => "{\"type\": \"command\", \"event\": ".into(),
        3 => json!({"type": "teleport", "to": rng.point()}).to_string(),
        4 => json!([rng.number(), {"type": "hello"}]).to_string(),
        5 => {
            let points: Vec<Value> = (0..rng.below(20_000)).map(|_| rng.point()).collect();
            json!({"type": "define", "path": points}).to_string()
        }
        _ => {
            let kind = *rng.pick(GuestMessage::TYPES);
            let mut m = json!({"type": kind});
            match kind {
                "hello" => {
                    m["protocol"] = json!(rng.below(3));
                    m["role"] = json!(rng.pick(&["operator", "observer", "king"]));
                    if rng.below(3) == 0 {
                        m["token"] = json!("wrong");
                    }
                }
                "mount" => {
                    m["experiment"] = json!(rng.pick(&["navigation", "teleoperation", "", "💥"]))
                }
                "define" => {
                    m["goal"] = json!({"x_mm": rng.number(), "y_mm": rng.number(), "tolerance_mm": rng.number()});
                    m["virtual_obstacles"] = json!([
                        {"shape": "circle", "x_mm": rng.number(), "y_mm": rng.number(), "radius_mm": rng.number()},
                        {"shape": "polygon", "points": [rng.point(), rng.point()]},
                    ]);
                    m["max_speed_mm_s"] = rng.number();
                    m["time_limit_s"] = rng.number();
                }
                "command" => {
                    m["event"] = json!(rng.below(1000));
                    if rng.below(2) == 0 {
                        m["v"] = rng.number();
                        m["w"] = rng.number();
                    } else {
                        m["left"] = rng.number();
                        m["right"] = rng.number();
                    }
                }
                "ping" | "pong" => m["t"] = rng.number(),
                _ => {}
            }
            m.to_string()
        }
    };
    Message::text(text)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fuzzed_clients_leave_the_host_serving() {
    let count: u64 = std::env::var("FUZZ_MESSAGES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(3_000);
    let seed: u64 = std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(1);
    // A fuzzed operator whose connection drops is held for the grace: a
    // short one, so the operator after the fuzzing waits seconds, not ten.
    let (mut host, url) = start_host(&["--camera", "sim", "--grace", "2"]);
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut clients: Vec<Option<_>> = (0..8).map(|_| None).collect();
    let (mut sent, mut connections) = (0u64, 0u64);
    while sent < count {
        let slot = rng.below(clients.len() as u64) as usize;
        if clients[slot].is_none() || rng.below(50) == 0 {
            clients[slot] = connect_async(&url).await.ok().map(|(ws, _)| ws);
            connections += 1;
            continue;
        }
        let ws = clients[slot].as_mut().expect("connected");
        let burst = 1 + rng.below(20);
        let mut failed = false;
        for _ in 0..burst {
            let m = message(&mut rng);
            sent += 1;
            if tokio::time::timeout(Duration::from_millis(200), ws.send(m))
                .await
                .map_or(true, |r| r.is_err())
            {
                failed = true;
                break;
            }
        }
        // Read what is there, sometimes: a client that never reads is fuzz too.
        if rng.below(3) == 0 {
            while let Ok(Some(Ok(_))) =
                tokio::time::timeout(Duration::from_millis(1), ws.next()).await
            {}
        }
        if failed || rng.below(30) == 0 {
            clients[slot] = None;
        }
    }
    drop(clients);
    let (rss, peak) = memory_mb(host.0.id());
    println!(
        "{sent} fuzzed messages over {connections} connections (seed {seed}); \
         the Host holds {rss:.0} MB, {peak:.0} MB at most"
    );
    assert!(host.0.try_wait().unwrap().is_none(), "the Host died");
    assert!(peak < 256.0, "the Host grew to {peak:.0} MB");
    // An operator finds the lab working.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let mut op = Peer::connect(&url).await;
    let mut welcomed = None;
    for _ in 0..50 {
        op.send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
            .await;
        welcomed = op.next_of("welcome", Duration::from_millis(200)).await;
        if welcomed.is_some() {
            break;
        }
    }
    assert!(
        welcomed.is_some(),
        "no operator is welcomed after the fuzzing"
    );
    op.start("navigation").await;
    for event in 1..=20 {
        assert_finite_feedback(&op.command(event, json!({"v": 100.0, "w": 0.2})).await);
    }
    op.send(json!({"type": "stop"})).await;
    assert_eq!(op.expect("done").await["summary"]["reason"], "stopped");
}
