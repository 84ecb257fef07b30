//! Surviving a dropped link: the operator's role and run are held for the
//! grace with the robot still, given back to the operator who says hello
//! with its `resume`, and freed when the grace runs out; the Guest
//! reconnects by itself through an outage of the Media.

use crate::common;

use std::time::{Duration, Instant};

use common::peer::Peer;
use common::{scratch, start_host, start_media};
use serde_json::{Value, json};
use vl_sim::{LinkModel, Profile};

async fn operator(url: &str) -> (Peer, String) {
    let mut op = Peer::connect(url).await;
    let welcome = op.hello("operator").await;
    let resume = welcome["resume"]
        .as_str()
        .expect("an operator gets a resume secret")
        .to_owned();
    (op, resume)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dropped_operator_gets_the_run_back_within_the_grace_and_loses_it_after() {
    let (_host, url) = start_host(&[
        "--grace",
        "1.5",
        "--camera",
        "none",
        "--experiments",
        "teleoperation",
    ]);
    let (mut op, resume) = operator(&url).await;
    op.start("teleoperation").await;
    let moving = op.command(1, json!({"v": 60, "w": 0})).await;
    assert!(moving["event"].as_u64() >= Some(1));
    // The link drops: no bye, the socket just goes.
    drop(op);
    let mut watcher = Peer::connect(&url).await;
    watcher.hello("observer").await;
    // Held still at once: 200 ms on, well inside the watchdog's 500 ms.
    let first = watcher.expect("feedback").await;
    let f = watcher.feedback_after(&first, 200.0).await;
    let wheels = f["wheels"]["left_mm_s"].as_f64().unwrap().abs()
        + f["wheels"]["right_mm_s"].as_f64().unwrap().abs();
    assert!(wheels < 5.0, "the robot is held: {f}");
    // Someone else may not take the held role.
    let mut other = Peer::connect(&url).await;
    other
        .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
        .await;
    let e = other.expect_error("operator_taken").await;
    assert!(
        e["message"].as_str().unwrap().contains("held for them"),
        "{e}"
    );
    // A wrong secret does not help either.
    let mut guesser = Peer::connect(&url).await;
    guesser
        .send(json!({"type": "hello", "protocol": 1, "role": "operator", "resume": "0123456789abcdef0123456789abcdef"}))
        .await;
    guesser.expect_error("operator_taken").await;
    // The operator is back: role, lab, definition and the run where it
    // stood; and so again after each of three drops in the one run, each
    // welcome with a fresh secret for the next.
    let mut resume = resume;
    let mut back = None;
    for drop_number in 1..=3u64 {
        let mut peer = Peer::connect(&url).await;
        peer.send(json!({"type": "hello", "protocol": 1, "role": "operator", "resume": resume}))
            .await;
        let welcome = peer.expect("welcome").await;
        assert_eq!(welcome["role"], "operator", "drop {drop_number}: {welcome}");
        let fresh = welcome["resume"]
            .as_str()
            .unwrap_or_else(|| panic!("drop {drop_number}: no fresh secret in {welcome}"))
            .to_owned();
        assert_ne!(fresh, resume, "each welcome has a new secret");
        resume = fresh;
        peer.expect("mounted").await;
        let started = peer.expect("started").await;
        assert_eq!(
            started["event"], drop_number,
            "the run goes on from its last event: {started}"
        );
        let again = peer
            .command(drop_number + 1, json!({"v": 60, "w": 0}))
            .await;
        assert!(again["event"].as_u64() >= Some(drop_number + 1), "{again}");
        if drop_number < 3 {
            // The link drops again mid-run.
            drop(peer);
            tokio::time::sleep(Duration::from_millis(200)).await;
        } else {
            back = Some(peer);
        }
    }
    let back = back.unwrap();
    // Dropped again, and this time gone for good: the run ends, the role is free.
    drop(back);
    let done = watcher
        .next_of("done", Duration::from_secs(5))
        .await
        .expect("the run ends after the grace");
    assert_eq!(done["summary"]["reason"], "operator_left", "{done}");
    let mut next = Peer::connect(&url).await;
    let w = next.hello("operator").await;
    assert_eq!(w["role"], "operator");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_who_says_bye_frees_the_role_at_once() {
    let (_host, url) = start_host(&["--grace", "30", "--camera", "none"]);
    let (mut op, _) = operator(&url).await;
    op.start("teleoperation").await;
    op.send(json!({"type": "bye"})).await;
    let mut next = Peer::connect(&url).await;
    let started = Instant::now();
    loop {
        next.send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
            .await;
        let reply: Value = next
            .next_of("welcome", Duration::from_millis(500))
            .await
            .unwrap_or(Value::Null);
        if reply["role"] == "operator" {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(3),
            "the role is freed on bye"
        );
        next = Peer::connect(&url).await;
    }
}

/// The whole path: `vl guest` teleoperates through `vl media`, whose link
/// goes down for two seconds mid-run. The Guest reconnects by itself,
/// gets the run back and reaches the goal; an observer on the Host sees
/// the robot still while no operator is connected.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_guest_rides_out_an_outage_of_the_media() {
    let (_host, host_url) = start_host(&["--camera", "sim"]);
    let mut watcher = Peer::connect(&host_url).await;
    watcher.hello("observer").await;
    let dir = scratch("reconnect-outage");
    let outage = (3500.0, 5500.0);
    let model = LinkModel {
        disconnects: vec![outage],
        ..LinkModel::profile(Profile::Internet2)
    };
    let file = dir.join("outage.json");
    std::fs::write(&file, serde_json::to_string(&model).unwrap()).unwrap();
    let (_media, media_url) = start_media(&host_url, file.to_str().unwrap(), &[]);
    let t0 = Instant::now();
    let guest = tokio::task::spawn_blocking(move || {
        common::vl(&[
            "guest",
            "--headless",
            "--connect",
            &media_url,
            "--experiment",
            "teleoperation",
            "--timeout",
            "60",
            "--json",
        ])
    });
    // Watch the robot through the outage, straight from the Host.
    let mut moving_unattended = Vec::new();
    let mut feedback = 0;
    let end = t0 + Duration::from_millis(outage.1 as u64);
    let quiet_from = t0 + Duration::from_millis(outage.0 as u64 + 600);
    while Instant::now() < end {
        let Some(f) = watcher.next_of("feedback", Duration::from_secs(1)).await else {
            continue;
        };
        feedback += 1;
        let now = Instant::now();
        let speed = f["wheels"]["left_mm_s"].as_f64().unwrap().abs()
            + f["wheels"]["right_mm_s"].as_f64().unwrap().abs();
        if now > quiet_from && speed > 5.0 {
            moving_unattended.push((now - t0, speed));
        }
    }
    assert!(feedback > 50, "the observer saw the run");
    assert!(
        moving_unattended.is_empty(),
        "the robot moved with no operator: {moving_unattended:?}"
    );
    let out = guest.await.unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let report: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(report["reached_goal"], true, "{report}");
    assert_eq!(report["collisions"], 0, "{report}");
    assert!(
        report["sim_seconds"].as_f64().unwrap() > outage.0 / 1e3 - 2.0,
        "the run spanned the outage: {report}"
    );
}

/// Through a Media whose Host is down, the Guest says why (the Media tells
/// it) and counts its attempts up, backing off, until it gives up.
#[test]
fn through_a_media_whose_host_is_down_the_attempts_count_up() {
    // Nothing listens on the discard port (a free port could be taken by
    // another test's Host meanwhile).
    let nobody = "ws://127.0.0.1:9".to_owned();
    let (_media, url) = start_media(&nobody, "lan", &[]);
    let out = common::vl(&["guest", "--connect", &url, "--headless"]);
    assert_eq!(out.status.code(), Some(1));
    let said = common::stderr(&out);
    assert!(said.contains(&format!("the Host at {nobody}")), "{said}");
    assert!(said.contains("attempt 4"), "the count rises: {said}");
    let attempts = said.matches("attempt ").count();
    assert!(
        attempts < 12,
        "backing off, {attempts} attempts in 10 s: {said}"
    );
}
