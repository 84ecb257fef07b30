//! A lab made ready for the next user: after a run the Host drives the
//! robot back to the start pose by itself, on the simulator and on the
//! Khepera emulator's real serial timing, so the next run starts where the
//! first did and takes as long; a headless operator that finishes says
//! goodbye, so the next is welcomed at once.

use crate::common;

use std::time::Duration;

use common::peer::Peer;
use common::{start_emulator, start_host, start_khepera_host};
use serde_json::Value;

/// The lab's start pose in the navigation arena, mm.
const START: (f64, f64) = (100.0, 120.0);

/// A headless operator's whole run on `url`, as JSON.
fn run(url: &str, extra: &[&str]) -> Value {
    common::headless_run(url, 120, extra)
}

/// Real-time runs timed against each other share two cores badly: one
/// pair at a time.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Two runs in a row: both reach the goal, the second starts at the start
/// pose (after the drive back) and takes as long as the first.
fn two_runs_alike(url: &str, extra: &[&str]) {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let first = run(url, extra);
    let second = run(url, extra);
    for (which, r) in [("first", &first), ("second", &second)] {
        assert_eq!(r["reason"], "goal_reached", "{which} run: {r}");
    }
    let from = &second["planned"][0];
    let off =
        (from["x_mm"].as_f64().unwrap() - START.0).hypot(from["y_mm"].as_f64().unwrap() - START.1);
    assert!(
        off <= 6.0,
        "the second run starts {off:.1} mm from the start pose: {from}"
    );
    let (a, b) = (
        first["sim_seconds"].as_f64().unwrap(),
        second["sim_seconds"].as_f64().unwrap(),
    );
    assert!(
        (b - a).abs() <= 0.2 * a,
        "the second run took {b:.2} s, the first {a:.2} s"
    );
}

#[test]
fn on_the_simulator_the_second_run_starts_where_the_first_did() {
    let (_host, url) = start_host(&[]);
    two_runs_alike(&url, &[]);
}

#[test]
fn on_the_khepera_emulator_the_second_run_starts_where_the_first_did() {
    let (_emulator, device) = start_emulator(&[]);
    let (_host, url) = start_khepera_host(&device);
    // A goal in the open: without a camera, odometry alone carries the run.
    two_runs_alike(&url, &["--goal", "150,330"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_headless_operator_that_finishes_frees_the_role_at_once() {
    let (_host, url) = start_host(&[]);
    let finished = {
        let url = url.clone();
        tokio::task::spawn_blocking(move || run(&url, &["--goal", "150,330"]))
            .await
            .unwrap()
    };
    assert_eq!(finished["reason"], "goal_reached", "{finished}");
    // At once: the Guest closed only when the Host had answered its close,
    // which it does once it has taken the goodbye in.
    let mut next = Peer::connect(&url).await;
    next.send(serde_json::json!({"type": "hello", "protocol": 1, "role": "operator"}))
        .await;
    let answer = next
        .next_of_any(&["welcome", "error"], Duration::from_secs(5))
        .await
        .expect("an answer to hello");
    assert_eq!(answer["type"], "welcome", "{answer}");
    assert_eq!(answer["role"], "operator", "{answer}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn start_waits_while_the_lab_gets_ready() {
    let (_host, url) = start_host(&[]);
    let mut operator = Peer::connect(&url).await;
    operator.hello("operator").await;
    operator.start("teleoperation").await;
    // Drive off the start pose, then end the run.
    for event in 1..=40 {
        operator
            .command(event, serde_json::json!({"v": 120.0, "w": 0.0}))
            .await;
    }
    operator.send(serde_json::json!({"type": "stop"})).await;
    operator.expect("done").await;
    let status = operator.expect("status").await;
    assert_eq!(status["lab"], "getting_ready", "{status}");
    operator.send(serde_json::json!({"type": "start"})).await;
    let refused = operator.expect_error("not_allowed_now").await;
    assert!(
        refused["message"]
            .as_str()
            .unwrap()
            .contains("getting ready"),
        "{refused}"
    );
    // Back at the start, the lab is ready and a run may start.
    let ready = operator
        .next_of("status", Duration::from_secs(30))
        .await
        .expect("the lab ready again");
    assert_eq!(ready["lab"], "ready", "{ready}");
    let pose = operator.expect("feedback").await["pose"].clone();
    let off =
        (pose["x_mm"].as_f64().unwrap() - START.0).hypot(pose["y_mm"].as_f64().unwrap() - START.1);
    assert!(off <= 6.0, "ready {off:.1} mm from the start pose: {pose}");
    operator.send(serde_json::json!({"type": "start"})).await;
    operator.expect("started").await;
}
