//! Every run kept: the Host records each run as an MCAP file in Foxglove's
//! schemas, which an independent reader (Python's `mcap`, as Foxglove's
//! own tools read it) opens; a Guest downloads it over the socket and plays
//! it back to the summary it was sent live; a Host killed mid-run leaves a
//! file `vl record repair` makes whole up to its last half second; and the
//! socket gives a run's file to its own Guest only.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::common::peer::Peer;
use crate::common::{self, s, scratch, start_host, vl_json};

/// Foxglove's views and the schemas its panels know them by.
const FOXGLOVE: [(&str, &str); 7] = [
    ("/camera", "foxglove.CompressedImage"),
    ("/camera/annotations", "foxglove.ImageAnnotations"),
    ("/robot/pose", "foxglove.PoseInFrame"),
    ("/robot/true_pose", "foxglove.PoseInFrame"),
    ("/tf", "foxglove.FrameTransform"),
    ("/scene", "foxglove.SceneUpdate"),
    ("/log", "foxglove.Log"),
];

/// What Python's `mcap` reads in `file`, if it is here.
fn read_independently(file: &Path) -> Option<Value> {
    // `.ci/run` installs the mcap package.
    let python = common::python_with("mcap, zstandard")?;
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/recordings/read.py");
    let out = Command::new(python)
        .args([script, s(file)])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    Some(serde_json::from_slice(&out.stdout).expect("the reader prints JSON"))
}

/// `vl record info`'s count of messages on `topic`.
fn count(info: &Value, topic: &str) -> u64 {
    info["topics"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["topic"] == topic)
        .map_or(0, |t| t["messages"].as_u64().unwrap())
}

#[test]
fn a_run_is_recorded_for_foxglove_downloaded_and_replayed_to_the_same_summary() {
    let dir = scratch("recordings-run");
    let (recordings, downloads) = (dir.join("host"), dir.join("guest"));
    let (_host, url) = start_host(&["--recordings", s(&recordings)]);
    let report = common::headless_run(&url, 60, &["--download-to", s(&downloads)]);
    assert_eq!(report["reached_goal"], true, "{report}");
    let summary = &report["summary"];
    let name = summary["recording"]["name"]
        .as_str()
        .expect("the summary names its file");
    assert_eq!(summary["recording"]["dropped_frames"], 0);
    let file = PathBuf::from(report["downloaded"].as_str().expect("downloaded"));
    assert_eq!(
        std::fs::read(&file).unwrap(),
        std::fs::read(recordings.join(name)).unwrap(),
        "the download differs from the Host's file"
    );

    let info = vl_json(&["record", "info", s(&file), "--json"]);
    assert_eq!(info["complete"], true);
    assert_eq!(&info["summary"], summary);
    for (topic, schema) in FOXGLOVE {
        let found = info["topics"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["topic"] == topic);
        assert_eq!(
            found.map(|t| &t["schema"]),
            Some(&json!(schema)),
            "{topic}: {info}"
        );
    }
    // Feedback every 20 ms, for as long as the run's feedback spans.
    let seconds = info["feedback_seconds"].as_f64().unwrap();
    let feedback = count(&info, "/feedback") as f64;
    assert!(
        (feedback - seconds / 0.02).abs() <= 0.1 * seconds / 0.02 + 2.0,
        "{feedback} feedback in {seconds} s"
    );
    // Every frame the camera published: none dropped (above), each with its
    // annotations. How many it took is the camera's, which yields to the
    // control loop on a busy machine (measured by `vl host bench`).
    let frames = count(&info, "/camera");
    assert!(frames > 0, "no frames in {seconds} s");
    assert_eq!(count(&info, "/camera/annotations"), frames);
    // Beyond the run's first and last lines, what the Host logged meanwhile.
    assert!(count(&info, "/log") > 2, "{info}");

    let replayed = vl_json(&["guest", "--replay", s(&file), "--headless", "--json"]);
    assert_eq!(&replayed["summary"], summary, "the replay ends elsewhere");
    assert_eq!(replayed["feedback"], count(&info, "/feedback"));
    assert_eq!(replayed["frames"], frames);

    if let Some(read) = read_independently(&file) {
        assert_eq!(read["monotonic"], true, "log times go back");
        assert_eq!(read["jpegs"], frames, "not every image decodes");
        assert_eq!(&read["summary"], summary);
        for t in info["topics"].as_array().unwrap() {
            let topic = t["topic"].as_str().unwrap();
            assert_eq!(read["topics"][topic]["schema"], t["schema"], "{topic}");
            assert_eq!(read["topics"][topic]["count"], t["messages"], "{topic}");
            assert_eq!(read["topics"][topic]["encoding"], "json", "{topic}");
        }
    }

    let listed = vl_json(&["record", "ls", s(&recordings), "--json"]);
    assert_eq!(listed[0]["name"], name);
    assert_eq!(listed[0]["ending"], "goal_reached");

    let out = dir.join("export");
    let exported = vl_json(&["record", "export", s(&file), "--out", s(&out), "--json"]);
    assert_eq!(exported["feedback_rows"], count(&info, "/feedback"));
    assert_eq!(exported["frames"], frames);
    let csv = std::fs::read_to_string(out.join("feedback.csv")).unwrap();
    assert_eq!(csv.lines().count() as u64, count(&info, "/feedback") + 1);
    let pngs = std::fs::read_dir(out.join("frames")).unwrap().count() as u64;
    assert_eq!(pngs, frames);
    let exported_summary: Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(&exported_summary, summary);
    // The run's pictures, as SVG and PNG.
    for plot in ["paths", "tracking", "round_trip"] {
        for kind in ["svg", "png"] {
            let picture = out.join(format!("{plot}.{kind}"));
            assert!(
                std::fs::metadata(&picture).is_ok_and(|m| m.len() > 1000),
                "{picture:?}"
            );
        }
    }
    assert_eq!(
        exported["plots"].as_array().map(Vec::len),
        Some(3),
        "{exported}"
    );
}

/// The run's file, once the Host has begun it.
fn first_recording(dir: &Path, within: Duration) -> PathBuf {
    let deadline = Instant::now() + within;
    loop {
        let found = std::fs::read_dir(dir).ok().and_then(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .find(|p| p.extension().is_some_and(|x| x == "mcap"))
        });
        if let Some(file) = found {
            return file;
        }
        assert!(Instant::now() < deadline, "no run was recorded in {dir:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_host_killed_mid_run_leaves_a_file_repair_makes_whole() {
    let dir = scratch("recordings-kill");
    let recordings = dir.join("host");
    // The maze's goal is further than five seconds away.
    let (mut host, url) = start_host(&["--arena", "maze", "--recordings", s(&recordings)]);
    let mut guest = common::vl_command()
        .args(["guest", "--connect", &url, "--headless", "--timeout", "60"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let file = first_recording(&recordings, Duration::from_secs(30));
    // Until the file holds five seconds of the run (the recorder flushes
    // every second), with the run still going: then the Host is killed.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let info = common::vl(&["record", "info", s(&file), "--json"]);
        let seconds = serde_json::from_slice::<Value>(&info.stdout)
            .ok()
            .and_then(|i| i["feedback_seconds"].as_f64())
            .unwrap_or(0.0);
        if seconds >= 5.0 {
            break;
        }
        assert!(
            guest.try_wait().unwrap().is_none(),
            "the run ended before five seconds were recorded"
        );
        assert!(
            Instant::now() < deadline,
            "the file never held 5 s of the run"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    host.0.kill().unwrap(); // SIGKILL
    host.0.wait().unwrap();
    let _ = guest.kill();
    let _ = guest.wait();

    let info = vl_json(&["record", "info", s(&file), "--json"]);
    assert_eq!(info["complete"], false, "a killed Host finished its file");
    assert_eq!(info["summary"], Value::Null);
    let repaired = dir.join("repaired.mcap");
    let report = vl_json(&[
        "record",
        "repair",
        s(&file),
        "--out",
        s(&repaired),
        "--json",
    ]);
    assert_eq!(report["was_complete"], false);
    let kept = report["feedback_seconds"].as_f64().unwrap();
    assert!(
        kept >= 4.0,
        "only {kept:.2} s of feedback survived the kill"
    );
    let info = vl_json(&["record", "info", s(&repaired), "--json"]);
    assert_eq!(info["complete"], true);
    if let Some(read) = read_independently(&repaired) {
        assert!(read["feedback_seconds"].as_f64().unwrap() >= 4.0, "{read}");
        assert_eq!(read["monotonic"], true);
    }
}

/// The runs the Host lists for `peer`, once it lists any: the recorder
/// (a thread behind the lab, here in a debug build on a busy machine) may
/// not have opened a short run's file yet when its `done` arrives.
async fn runs_listed(peer: &mut Peer) -> Value {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        peer.send(json!({"type": "recordings"})).await;
        let listed = peer.expect("recordings").await;
        if !listed["runs"].as_array().unwrap().is_empty() || Instant::now() > deadline {
            return listed;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Stops the run under way: the name of its recording.
async fn stopped_recording(operator: &mut Peer) -> String {
    operator.send(json!({"type": "stop"})).await;
    let done = operator.expect("done").await;
    done["summary"]["recording"]["name"]
        .as_str()
        .unwrap_or_else(|| panic!("not recorded: {done}"))
        .to_owned()
}

/// A run with the operator's commands, ended by the operator: its `done`.
async fn recorded_run(operator: &mut Peer) -> Value {
    operator.hello("operator").await;
    operator.start("teleoperation").await;
    operator.command(1, json!({"v": 20.0, "w": 0.0})).await;
    operator.send(json!({"type": "stop"})).await;
    operator.expect("done").await
}

#[tokio::test(flavor = "multi_thread")]
async fn a_run_is_its_own_guests_and_bad_requests_are_refused() {
    let dir = scratch("recordings-socket");
    // Where runs go comes from the lab's file, beside it.
    let lab = dir.join("lab.toml");
    std::fs::write(&lab, "recordings = \"runs\"\nkeep-gb = 1\n").unwrap();
    let (_host, url) = start_host(&["--config", s(&lab)]);
    let mut early = Peer::connect(&url).await;
    early.send(json!({"type": "recordings"})).await;
    early.expect_error("hello_first").await;

    let mut operator = Peer::connect(&url).await;
    let done = recorded_run(&mut operator).await;
    let name = done["summary"]["recording"]["name"]
        .as_str()
        .expect("recorded")
        .to_owned();
    let listed = runs_listed(&mut operator).await;
    assert_eq!(listed["runs"][0]["name"], name.as_str(), "{listed}");
    let file = dir.join("runs").join(&name);
    assert!(file.exists(), "not recorded where lab.toml says");
    assert_eq!(listed["runs"][0]["experiment"], "teleoperation");

    // Someone else sees nothing of it and gets nothing of it.
    let mut other = Peer::connect(&url).await;
    other.hello("observer").await;
    other.send(json!({"type": "recordings"})).await;
    assert_eq!(other.expect("recordings").await["runs"], json!([]));
    other
        .send(json!({"type": "download", "name": name, "offset": 0}))
        .await;
    other.expect_error("unknown_recording").await;

    for bad in ["../../etc/passwd.mcap", "/etc/passwd", "run.txt", ""] {
        operator
            .send(json!({"type": "download", "name": bad}))
            .await;
        operator.expect_error("bad_message").await;
    }
    operator
        .send(json!({"type": "download", "name": "run-1-1.mcap"}))
        .await;
    operator.expect_error("unknown_recording").await;
    // Its own run comes as binary parts once its file is closed (until
    // then the Host says to ask again).
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let frames = operator.frames;
        operator
            .send(json!({"type": "download", "name": name}))
            .await;
        operator.send(json!({"type": "ping", "t": 1.0})).await;
        let answer = operator
            .next_of_any(&["pong", "error"], Duration::from_secs(5))
            .await
            .expect("an answer");
        if answer["type"] == "pong" && operator.frames > frames {
            break;
        }
        if answer["type"] == "error" {
            assert_eq!(answer["code"], "not_allowed_now", "{answer}");
        }
        assert!(Instant::now() < deadline, "the run's file never came");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    operator
        .send(json!({"type": "download", "name": name, "offset": 1u64 << 40}))
        .await;
    operator.expect_error("unknown_recording").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn the_time_between_runs_is_recorded_for_administrators_only() {
    let dir = scratch("recordings-idle");
    let (_host, url) = start_host(&["--recordings", s(&dir), "--record-idle"]);
    let mut operator = Peer::connect(&url).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let done = recorded_run(&mut operator).await;
    let run = done["summary"]["recording"]["name"]
        .as_str()
        .unwrap()
        .to_owned();
    let listed = runs_listed(&mut operator).await;
    assert_eq!(listed["runs"].as_array().unwrap().len(), 1, "{listed}");
    assert_eq!(listed["runs"][0]["name"], run.as_str());

    // Before the run, the run, and after it (still being written), once
    // the recorder has closed the run's file and begun the next.
    let deadline = Instant::now() + Duration::from_secs(10);
    let all = loop {
        let all = vl_json(&["record", "ls", s(&dir), "--json"]);
        if all.as_array().unwrap().len() == 3 || Instant::now() > deadline {
            break all;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let names: Vec<&str> = all
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(names.len(), 3, "{all}");
    assert!(
        names[0].starts_with("idle-") && names[2].starts_with("idle-"),
        "{names:?}"
    );
    assert_eq!(names[1], run);
    assert_eq!(all[2]["experiment"], Value::Null);
    let before = dir.join(names[2]);
    let info = vl_json(&["record", "info", s(&before), "--json"]);
    assert_eq!(
        info["complete"], true,
        "the run's start closes the time before it"
    );
    assert!(count(&info, "/feedback") > 0, "{info}");
    assert_eq!(count(&info, "/summary"), 0);
}

#[test]
fn a_run_saved_as_a_task_runs_again_as_it_was() {
    let dir = scratch("tasks-cli");
    let (_host, url) = start_host(&["--no-record"]);
    let run = |extra: &[&str]| {
        let args = [&["guest", "--connect", &url, "--headless", "--json"], extra].concat();
        common::vl_command()
            .env("XDG_CONFIG_HOME", &dir)
            .args(&args)
            .output()
            .unwrap()
    };
    let first = run(&["--save-task", "lap"]);
    assert!(first.status.success(), "{}", common::stderr(&first));
    let first: Value = serde_json::from_slice(&first.stdout).unwrap();
    assert!(dir.join("vl/tasks/lap.json").exists());
    let again = run(&["--task", "lap"]);
    assert!(again.status.success(), "{}", common::stderr(&again));
    let again: Value = serde_json::from_slice(&again.stdout).unwrap();
    assert_eq!(
        again["planned"], first["planned"],
        "the task ran another path"
    );
    assert_eq!(again["reached_goal"], true);

    let missing = run(&["--task", "nope"]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        common::stderr(&missing).contains("saved: lap"),
        "{}",
        common::stderr(&missing)
    );
    let outside = run(&["--save-task", "../lap"]);
    assert_eq!(outside.status.code(), Some(2));
    assert!(common::stderr(&outside).contains("cannot name a task"));
}

#[test]
fn files_that_are_no_recordings_are_named_not_panicked_on() {
    let dir = scratch("recordings-bad");
    let text = dir.join("notes.mcap");
    std::fs::write(&text, "not a recording").unwrap();
    let missing = dir.join("missing.mcap");
    common::refused(&["record", "info", s(&text)], "is not an MCAP recording");
    common::refused(&["record", "info", s(&missing)], "missing.mcap");
    common::refused(&["record", "repair", s(&text)], "is not an MCAP recording");
    common::refused(&["guest", "--replay", s(&text), "--headless"], "--replay:");
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &b"\x89MCAP0\r\n"[..]).unwrap();
    common::refused(
        &["guest", "--replay", s(&cut), "--headless"],
        "holds no run",
    );
}

/// Strangers write nothing into the experiment's data: sockets that never
/// say hello send pongs echoing times never sent, an observer sends what
/// only the operator may; the run's file keeps its own log and round trips
/// (issue 43, item 11).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn strangers_write_nothing_into_a_run() {
    let dir = scratch("recordings-strangers");
    let recordings = dir.join("host");
    let (_host, url) = start_host(&["--recordings", s(&recordings)]);
    let mut operator = Peer::connect(&url).await;
    operator.hello("operator").await;
    operator.start("teleoperation").await;
    let mut observer = Peer::connect(&url).await;
    observer.hello("observer").await;
    for _ in 0..100 {
        observer
            .send(json!({"type": "mount", "experiment": "navigation"}))
            .await;
    }
    for _ in 0..40 {
        if let Ok(mut stranger) = Peer::try_connect(&url).await {
            for _ in 0..15 {
                let pong = json!({"type": "pong", "t": -1e12}).to_string();
                if futures_util::SinkExt::send(
                    &mut stranger.ws,
                    tokio_tungstenite::tungstenite::Message::text(pong),
                )
                .await
                .is_err()
                {
                    break;
                }
            }
        }
    }
    tokio::time::sleep(Duration::from_secs(1)).await;
    let name = stopped_recording(&mut operator).await;
    let file = recordings.join(name);
    let deadline = Instant::now() + Duration::from_secs(10);
    let info = loop {
        let info = vl_json(&["record", "info", s(&file), "--json"]);
        if info["complete"] == true || Instant::now() > deadline {
            break info;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let topics: Vec<String> = info["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| format!("{} {}", t["topic"], t["messages"]))
        .collect();
    let log = count(&info, "/log");
    assert!(log < 60, "{log} log lines: {topics:?}");
    let round_trips = count(&info, "/round_trip");
    assert!(round_trips < 200, "{round_trips} round trips: {topics:?}");
}

/// A Guest asking for a part of its run again and again, as fast as it
/// can, draws no more than 8 MiB a second (16 at once), where it drew 200
/// parts a second (issue 43, item 8: a budget for what a client draws).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn asking_for_parts_faster_draws_nothing_faster() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let dir = scratch("recordings-drawn");
    let (_host, url) = start_host(&["--recordings", s(&dir), "--camera", "sim"]);
    let mut operator = Peer::connect(&url).await;
    operator.hello("operator").await;
    operator.start("teleoperation").await;
    for event in 1..=60 {
        operator.command(event, json!({"v": 0.0, "w": 1.0})).await;
    }
    let name = stopped_recording(&mut operator).await;
    // The recorder closes the file a moment after `done`.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let size = std::fs::metadata(dir.join(&name)).unwrap().len();
    assert!(size > 50_000, "a run of {size} bytes");
    let (mut sink, mut source) = futures_util::StreamExt::split(operator.ws);
    let drawn = Arc::new(AtomicUsize::new(0));
    let reading = {
        let drawn = drawn.clone();
        tokio::spawn(async move {
            while let Some(Ok(message)) = futures_util::StreamExt::next(&mut source).await {
                if message.is_binary() {
                    drawn.fetch_add(message.len(), Ordering::Relaxed);
                }
            }
        })
    };
    let asking = tokio::spawn(async move {
        let ask = json!({"type": "download", "name": name, "offset": 0}).to_string();
        loop {
            let text = tokio_tungstenite::tungstenite::Message::text(ask.clone());
            if futures_util::SinkExt::send(&mut sink, text).await.is_err() {
                return;
            }
        }
    });
    let seconds = 5.0;
    tokio::time::sleep(Duration::from_secs_f64(seconds)).await;
    let drawn = drawn.load(Ordering::Relaxed) as f64;
    asking.abort();
    reading.abort();
    let most = (8.0 * seconds + 16.0) * 1024.0 * 1024.0 * 1.2;
    println!("parts of a {size}-byte run: {drawn:.0} bytes drawn in {seconds} s");
    assert!(drawn < most, "{drawn:.0} bytes drawn in {seconds} s");
    assert!(drawn > 8.0 * 1024.0 * 1024.0, "only {drawn:.0} bytes drawn");
}
