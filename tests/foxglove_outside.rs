//! Foxglove's own libraries, outside vl, look at the lab (issue 44):
//! `tests/foxglove/check.mjs` (Node, with `@foxglove/ws-protocol`,
//! `@mcap/core` and the official `@foxglove/schemas` checked by ajv)
//! watches a run live and reads its recording, validating every message;
//! and that Foxglove's JSON Schema parser reads every channel's schema (by
//! its rules, as Lichtblick's `parseJsonSchema` has them);
//! drives the robot through the services and `/cmd_vel` as the operator,
//! and tries as someone else; and opens ten clients at once.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::common::{self, s, scratch, start_host};

/// The folder of the outside client: `.ci/run` installs its packages.
fn checker() -> Option<&'static Path> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/foxglove"));
    let node = Command::new("node").arg("--version").output();
    if !node.is_ok_and(|o| o.status.success()) || !dir.join("node_modules/@foxglove").is_dir() {
        common::missing(
            "Node.js with Foxglove's libraries",
            "npm ci --prefix tests/foxglove (as .ci/run does)",
        );
        return None;
    }
    Some(dir)
}

/// What `check.mjs ARGS…` reports.
fn check(args: &[&str]) -> Option<Value> {
    let dir = checker()?;
    let out = Command::new("node")
        .arg(dir.join("check.mjs"))
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    Some(serde_json::from_slice(&out.stdout).expect("the checker prints JSON"))
}

fn count(report: &Value, topic: &str) -> u64 {
    report["counts"][topic].as_u64().unwrap_or(0)
}

/// Every channel of the lab in 3D and its numbers, live and recorded.
const VIEWS: [(&str, &str); 13] = [
    ("/camera", "foxglove.CompressedImage"),
    ("/camera/annotations", "foxglove.ImageAnnotations"),
    ("/camera/calibration", "foxglove.CameraCalibration"),
    ("/tf_static", "foxglove.FrameTransform"),
    ("/robot/pose", "foxglove.PoseInFrame"),
    ("/tf", "foxglove.FrameTransform"),
    ("/scene", "foxglove.SceneUpdate"),
    ("/map", "foxglove.Grid"),
    ("/cspace", "foxglove.Grid"),
    ("/path", "foxglove.PosesInFrame"),
    ("/forecast/seeds", "foxglove.PosesInFrame"),
    ("/robot/ir", "foxglove.LaserScan"),
    ("/robot/motion", "vl.Motion"),
];

#[test]
fn every_message_of_a_run_is_valid_to_foxglove_live_and_recorded() {
    let Some(_) = checker() else { return };
    let recordings = scratch("foxglove-outside");
    let (_host, url) = start_host(&["--camera", "sim", "--recordings", s(&recordings)]);
    // Between runs: the lab is there at once, and every message is valid.
    let idle = check(&["live", &url, "2"]).unwrap();
    assert_eq!(idle["bad"], serde_json::json!([]), "{idle}");
    assert_eq!(idle["unreadable"], serde_json::json!([]), "{idle}");
    for topic in [
        "/scene",
        "/map",
        "/cspace",
        "/camera/calibration",
        "/tf_static",
        "/status",
    ] {
        assert!(
            count(&idle, topic) >= 1,
            "{topic} not sent between runs: {idle}"
        );
    }
    assert_eq!(idle["close"], 1000, "a client's close is answered: {idle}");
    let capabilities = &idle["serverInfo"]["capabilities"];
    for capability in ["clientPublish", "services", "time"] {
        assert!(
            capabilities
                .as_array()
                .unwrap()
                .contains(&Value::from(capability)),
            "{idle}"
        );
    }
    assert!(
        idle["times"].as_u64().unwrap() >= 5,
        "the time is told: {idle}"
    );
    // During a navigation run, joined late: the latched channels at once.
    let run_url = url.clone();
    let run = std::thread::spawn(move || common::headless_run(&run_url, 90, &[]));
    std::thread::sleep(std::time::Duration::from_secs(4));
    let live = check(&["live", &url, "5"]).unwrap();
    let report = run.join().unwrap();
    assert_eq!(report["reached_goal"], true, "{report}");
    assert_eq!(live["bad"], serde_json::json!([]), "{live}");
    assert_eq!(live["unreadable"], serde_json::json!([]), "{live}");
    assert_eq!(
        live["serverInfo"]["sessionId"], idle["serverInfo"]["sessionId"],
        "one session a Host start"
    );
    for (topic, schema) in VIEWS {
        assert_eq!(live["channels"][topic], schema, "{topic}: {live}");
    }
    for topic in [
        "/definition",
        "/forecast",
        "/lab",
        "/path",
        "/forecast/seeds",
    ] {
        let first = live["latched_first"][topic].as_u64();
        assert!(first.is_some_and(|ms| ms < 1000), "{topic} latched: {live}");
    }
    assert!(count(&live, "/robot/motion") >= 50, "{live}");
    assert!(
        count(&live, "/round_trip") >= 1,
        "the Guest's round trips: {live}"
    );
    assert!(
        live["summary"]["path_poses"].as_u64().unwrap() >= 2,
        "{live}"
    );
    // The tracking error, while the run follows its path.
    assert!(live["tracked"].as_u64().unwrap_or(0) >= 10, "{live}");
    // The run's recording, read by @mcap/core: every message valid too.
    let file = std::fs::read_dir(&recordings)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .max_by_key(|p| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0))
        .expect("a recording");
    let recorded = check(&["mcap", s(&file)]).unwrap();
    assert_eq!(recorded["bad"], serde_json::json!([]), "{recorded}");
    assert_eq!(recorded["unreadable"], serde_json::json!([]), "{recorded}");
    for (topic, schema) in VIEWS {
        assert_eq!(
            recorded["channels"][topic], schema,
            "{topic} recorded: {recorded}"
        );
    }
}

#[test]
fn the_operator_drives_from_foxglove_and_nobody_else_does() {
    let Some(_) = checker() else { return };
    let dir = scratch("foxglove-drive");
    let users = dir.join("users.toml");
    common::account(&users, "ada", "operator", "correct horse");
    common::account(&users, "bob", "observer", "battery staple");
    let (_host, url) = start_host(&["--no-record", "--users", s(&users)]);
    // Bob, who may only watch, cannot take control; nobody's Twists move
    // the robot without it.
    let refused = check(&["live", &url, "2", "drive", "bob", "battery staple"]).unwrap();
    let failures: Vec<&Value> = refused["responses"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["failure"].is_string())
        .collect();
    assert!(!failures.is_empty(), "{refused}");
    // How far the robot went from where the client first saw it.
    let stayed = |report: &Value| report["farthest_mm"].as_f64().unwrap();
    assert!(stayed(&refused) < 2.0, "bob moved the robot: {refused}");
    let statuses = refused["statuses"].to_string();
    assert!(statuses.contains("only the operator drives"), "{refused}");
    let intruder = check(&["live", &url, "2", "intrude"]).unwrap();
    assert!(stayed(&intruder) < 2.0, "{intruder}");
    assert!(
        intruder["statuses"]
            .to_string()
            .contains("only the operator drives"),
        "{intruder}"
    );
    // Ada, logged in through the service, drives forward at 60 mm/s.
    let driven = check(&["live", &url, "3", "drive", "ada", "correct horse"]).unwrap();
    let moved = stayed(&driven);
    assert!(
        moved > 40.0,
        "ada's Twists moved the robot {moved} mm: {driven}"
    );
    assert_eq!(driven["bad"], serde_json::json!([]), "{driven}");
}

#[test]
fn ten_foxglove_clients_at_once_from_one_address_all_get_server_info() {
    let Some(_) = checker() else { return };
    let (_first, url) = start_host(&["--no-record"]);
    let first = check(&["hello", &url, "10"]).unwrap();
    assert_eq!(first["got"], 10, "{first}");
    assert_eq!(first["sessions"].as_array().unwrap().len(), 1, "{first}");
    // Another Host start is another session.
    let (_second, url) = start_host(&["--no-record"]);
    let second = check(&["hello", &url, "1"]).unwrap();
    assert_ne!(
        first["sessions"][0], second["sessions"][0],
        "{first} {second}"
    );
}
