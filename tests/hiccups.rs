//! Hiccups heal: a Host frozen for 0.7 s (its serial guard stops the robot
//! meanwhile) and a robot that pauses for 2 s, each again and again, and
//! every time a new run starts within 5 s of the hiccup's end, without
//! restarting anything. It runs alone (tests/alone.rs): the 5 s are the
//! lab's, not a busy test runner's.

use crate::common;

use std::time::{Duration, Instant};

use serde_json::json;

use common::peer::Peer;
use common::{start_emulator, start_khepera_host_with};

/// Sends `signal` (SIGSTOP, SIGCONT) to process `pid`.
fn signal(pid: u32, signal: libc::c_int) {
    // SAFETY: kill only reads its integer arguments.
    let sent = unsafe { libc::kill(pid as libc::pid_t, signal) };
    assert_eq!(sent, 0, "signal {signal} to {pid}");
}

/// Starts a new run and drives it one command, trying for `within`: how
/// long it took, or `None` if it never did.
async fn new_run_within(op: &mut Peer, within: Duration) -> Option<Duration> {
    let began = Instant::now();
    while began.elapsed() < within {
        op.send(json!({"type": "start"})).await;
        let Some(reply) = answer_to_start(op).await else {
            continue;
        };
        if reply["type"] == "error" {
            // A run still going makes way; one stopping (or ended by a
            // fault) ends by itself. Its end is waited for, not guessed.
            let message = reply["message"].as_str().unwrap_or_default();
            if message.contains("execute.running") {
                op.send(json!({"type": "stop"})).await;
            }
            if message.contains("execute.running") || message.contains("execute.stopping") {
                op.next_of("done", Duration::from_secs(1)).await;
            } else {
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            continue;
        }
        // The robot must answer the run's first command, too.
        let event = reply["event"].as_u64().unwrap_or(0) + 1;
        op.send(json!({"type": "command", "event": event, "v": 50.0, "w": 0.0}))
            .await;
        let answered = tokio::time::timeout(Duration::from_secs(2), async {
            loop {
                let v = op
                    .next_of_any(&["feedback", "done"], Duration::from_secs(2))
                    .await?;
                if v["type"] == "done" {
                    return None;
                }
                if v["event"].as_u64() >= Some(event) {
                    return Some(());
                }
            }
        })
        .await;
        if matches!(answered, Ok(Some(()))) {
            return Some(began.elapsed());
        }
    }
    None
}

/// The answer to a `start`: `started`, or an error refusing it — not the
/// refusal of an earlier stop or command still on its way.
async fn answer_to_start(op: &mut Peer) -> Option<serde_json::Value> {
    loop {
        let reply = op
            .next_of_any(&["started", "error"], Duration::from_millis(500))
            .await?;
        let message = reply["message"].as_str().unwrap_or_default();
        if !(message.starts_with("cannot stop") || message.starts_with("cannot drive")) {
            return Some(reply);
        }
    }
}

/// Hiccups heal: a Host frozen for 0.7 s (its guard stops the robot
/// meanwhile) and a robot that pauses for 2 s, each again and again, and
/// every time a new run starts within 5 s of the hiccup's end without
/// restarting anything.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frozen_host_and_a_paused_robot_are_driven_again_within_5_s() {
    let _alone = crate::alone().await;
    let (emulator, device) = start_emulator(&[]);
    // Healing is timed here, not the drive back to the start pose.
    let (host, url) = start_khepera_host_with(&device, &["--no-reset"]);
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    op.start("navigation").await;
    op.command(1, json!({"v": 100.0, "w": 0.0})).await;
    let within = Duration::from_secs(5);
    for (who, pid, pause) in [
        ("Host", host.0.id(), Duration::from_millis(700)),
        ("Host", host.0.id(), Duration::from_millis(700)),
        ("Host", host.0.id(), Duration::from_millis(700)),
        ("robot", emulator.0.id(), Duration::from_secs(2)),
        ("robot", emulator.0.id(), Duration::from_secs(2)),
        ("robot", emulator.0.id(), Duration::from_secs(2)),
    ] {
        signal(pid, libc::SIGSTOP);
        tokio::time::sleep(pause).await;
        signal(pid, libc::SIGCONT);
        let took = new_run_within(&mut op, within).await;
        println!("the {who} paused for {pause:?}: a new run after {took:?}");
        assert!(
            took.is_some(),
            "the {who} paused for {pause:?}: no run within {within:?}"
        );
    }
}
