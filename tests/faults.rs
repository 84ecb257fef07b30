//! Fault injection over real sockets and processes: numbers that are not
//! speeds, floods, half-sent frames, idle sockets by the thousand, silent
//! and frozen operators, a Host killed mid-run, a robot line that comes and
//! goes, and hand-overs in quick succession. Each case is bounded in time
//! and count, on loopback only; each prints what it measured.

use crate::common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::json;
use tokio::io::AsyncWriteExt;

use common::peer::{Peer, assert_finite_feedback};
use common::{VlProcess, start_emulator, start_host, start_khepera_host, vl_bin};

/// The command that once poisoned the simulator with NaN for ever.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_turn_of_1e307_leaves_every_later_feedback_finite() {
    let (_host, url) = start_host(&["--camera", "none"]);
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    op.start("navigation").await;
    let hit = op.command(1, json!({"v": 0.0, "w": 1e307})).await;
    assert_finite_feedback(&hit);
    for (event, drive) in [
        (2, json!({"v": 1e308, "w": -1e308})),
        (3, json!({"left": -1.7e308, "right": 5e-324})),
        (4, json!({"v": 100.0, "w": 0.0})),
    ] {
        assert_finite_feedback(&op.command(event, drive).await);
    }
    let _ = op.ws.close(None).await;
    // The next operator finds the lab as it should be.
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut next = Peer::connect(&url).await;
    next.hello("operator").await;
    next.start("navigation").await;
    let f = next.command(1, json!({"v": 150.0, "w": 0.0})).await;
    assert_finite_feedback(&f);
    let later = next.command(20, json!({"v": 150.0, "w": 0.0})).await;
    assert_finite_feedback(&later);
}

/// Under `ulimit -n 1024`, eleven hundred idle sockets never lock a new
/// client out: the oldest silent ones make room.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_sockets_by_the_thousand_never_lock_a_client_out() {
    let script = format!(
        "ulimit -n 1024 && exec {} host --robot sim --camera none --listen 127.0.0.1:0",
        vl_bin()
    );
    let mut child = Command::new("sh")
        .args(["-c", &script])
        .stdout(Stdio::piped())
        .spawn()
        .expect("sh starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let _host = VlProcess(child);
    let url = line
        .trim()
        .trim_start_matches("vl host listening on ")
        .to_owned();
    let addr = url.trim_start_matches("ws://").to_owned();
    let mut idle = Vec::new();
    for _ in 0..1100 {
        match tokio::net::TcpStream::connect(&addr).await {
            Ok(s) => idle.push(s),
            Err(e) => panic!("connecting idle socket {}: {e}", idle.len()),
        }
    }
    // A newcomer gets in, though, as a Guest does, it may have to try again:
    // idle sockets the kernel queued past the listen backlog are accepted
    // after it, and each may evict the oldest one still shaking hands.
    let started = Instant::now();
    let mut attempts = 0;
    let mut newcomer = loop {
        attempts += 1;
        match Peer::try_connect(&url).await {
            Ok(peer) => break peer,
            Err(e) if attempts < 3 => println!("attempt {attempts}: {e}"),
            Err(e) => panic!("a newcomer was locked out {attempts} times: {e}"),
        }
    };
    let welcome = newcomer.hello("operator").await;
    println!(
        "1100 idle sockets open; a new operator welcomed in {:.1} ms ({attempts} attempt{})",
        started.elapsed().as_secs_f64() * 1e3,
        if attempts == 1 { "" } else { "s" }
    );
    assert_eq!(welcome["role"], "operator");
    // Writing on them all does not change that.
    for s in &mut idle {
        let _ = s.write_all(b"GET / HTTP/1.1\r\n").await;
    }
    let mut another = Peer::connect(&url).await;
    assert_eq!(another.hello("observer").await["role"], "observer");
}

/// An operator who stops commanding loses the run and the role after the
/// lease; one who freezes (reads and sends nothing) is dropped after the
/// ping timeout and, its link as good as dropped, loses the role after the
/// grace; either way another client can take over.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn silent_and_frozen_operators_lose_the_role() {
    let (_host, url) = start_host(&[
        "--camera",
        "none",
        "--lease",
        "1",
        "--ping-timeout",
        "1.5",
        "--grace",
        "1",
    ]);
    let mut silent = Peer::connect(&url).await;
    silent.hello("operator").await;
    silent.start("teleoperation").await;
    silent.command(1, json!({"v": 100.0, "w": 0.0})).await;
    let started = Instant::now();
    // It answers the Host's pings (Peer does while it waits): only the
    // lease can end its run.
    let e = silent.expect("error").await;
    assert_eq!(e["code"], "timeout", "{e}");
    assert!(e["message"].as_str().unwrap().contains("no command"), "{e}");
    let done = silent.expect("done").await;
    assert_eq!(done["summary"]["reason"], "operator_silent", "{done}");
    println!(
        "a silent operator lost the run after {:.2} s",
        started.elapsed().as_secs_f64()
    );
    // The next operator freezes: holds its socket, reads and sends nothing.
    let mut next = Peer::connect(&url).await;
    assert_eq!(next.hello("operator").await["role"], "operator");
    let frozen_at = Instant::now();
    let mut taker = Peer::connect(&url).await;
    taker
        .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
        .await;
    assert_eq!(taker.expect("error").await["code"], "operator_taken");
    let mut welcomed = None;
    for _ in 0..40 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        taker
            .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
            .await;
        if let Some(w) = taker.next_of("welcome", Duration::from_millis(100)).await {
            welcomed = Some(w);
            break;
        }
    }
    let freeze = frozen_at.elapsed().as_secs_f64();
    drop(next);
    assert!(welcomed.is_some(), "the frozen operator kept the role");
    println!("a frozen operator lost the role after {freeze:.2} s");
}

/// `kill -9` of a Host driving a Khepera: the serial guard it started sends
/// the stop command at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_host_leaves_the_robot_stopped() {
    let mut emulator = common::vl_command()
        .args(["khepera-emu", "--log-commands"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("the emulator starts");
    let mut lines = BufReader::new(emulator.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    let _emulator = VlProcess(emulator);
    let device = first.rsplit(' ').next().unwrap().to_owned();
    let (mut host, url) = start_khepera_host(&device);
    let (tx, commands) = std::sync::mpsc::channel::<(Instant, String)>();
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            let command = line
                .split_once(' ')
                .map_or(line.clone(), |(_, c)| c.to_owned());
            if tx.send((Instant::now(), command)).is_err() {
                break;
            }
        }
    });
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    op.start("teleoperation").await;
    for event in 1..=20 {
        op.command(event, json!({"v": 150.0, "w": 0.0})).await;
    }
    let killed = Instant::now();
    host.0.kill().expect("kill -9");
    let _ = host.0.wait();
    let stopped = loop {
        let (at, command) = commands
            .recv_timeout(Duration::from_secs(2))
            .expect("the emulator heard a stop");
        if at >= killed && command == "D,0,0" {
            break at;
        }
    };
    let ms = stopped.duration_since(killed).as_secs_f64() * 1e3;
    println!("the robot was told to stop {ms:.1} ms after the Host was killed");
    assert!(ms < 300.0, "{ms:.1} ms");
}

/// The robot's line lost and back: clients hear `offline` then `online`,
/// a new run works without restarting the Host, and the log says so in a
/// few lines.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_robot_line_that_comes_back_is_driven_again() {
    let dir = common::scratch("line-back");
    let link = dir.join("khepera");
    let link = link.to_str().unwrap().to_owned();
    let (emulator, _) = start_emulator(&["--link", &link]);
    let mut host = common::vl_command()
        .args([
            "host",
            "--robot",
            "khepera",
            "--port",
            &link,
            "--listen",
            "127.0.0.1:0",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(host.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    let log = host.stderr.take().unwrap();
    let host = VlProcess(host);
    let url = first
        .trim()
        .trim_start_matches("vl host listening on ")
        .to_owned();
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    assert_eq!(op.expect("status").await["robot"], "online");
    op.start("teleoperation").await;
    op.command(1, json!({"v": 100.0, "w": 0.0})).await;

    drop(emulator);
    let offline = op.expect("status").await;
    assert_eq!(offline["robot"], "offline", "{offline}");
    assert_eq!(op.expect("done").await["summary"]["reason"], "fault");
    op.send(json!({"type": "start"})).await;
    assert_eq!(op.expect("error").await["code"], "robot_offline");
    tokio::time::sleep(Duration::from_secs(1)).await;

    let (_emulator, _) = start_emulator(&["--link", &link]);
    let online = op
        .next_of("status", Duration::from_secs(10))
        .await
        .expect("the Host finds the robot again");
    assert_eq!(online["robot"], "online", "{online}");
    op.send(json!({"type": "start"})).await;
    op.expect("started").await;
    let f = op.command(1, json!({"v": 100.0, "w": 0.0})).await;
    assert_finite_feedback(&f);
    op.send(json!({"type": "stop"})).await;
    op.expect("done").await;
    drop(op);
    drop(host);
    let lines: Vec<String> = BufReader::new(log).lines().map_while(Result::ok).collect();
    println!("the Host's log, {} lines:", lines.len());
    for l in &lines {
        println!("  {l}");
    }
    assert!(lines.len() <= 8, "{} log lines", lines.len());
}

/// Hand-overs in quick succession: a run's end never reaches the next run.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_hundred_hand_overs_never_cross_their_ends() {
    // Runs' ends are what is checked, not the drive back after each.
    let (_host, url) = start_host(&["--camera", "none", "--no-reset"]);
    let mut crossed = 0;
    for round in 0..200 {
        let mut op = Peer::connect(&url).await;
        let mut welcome = None;
        // The previous operator's leaving may not have reached the Host yet.
        for _ in 0..50 {
            op.send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
                .await;
            welcome = op.next_of("welcome", Duration::from_millis(200)).await;
            if welcome.is_some() {
                break;
            }
        }
        assert!(welcome.is_some(), "round {round}: never welcomed");
        op.start("teleoperation").await;
        op.command(1, json!({"v": 100.0, "w": 0.0})).await;
        // Whatever ends a run now ends this one, not a previous one.
        if op
            .next_of("done", Duration::from_millis(20))
            .await
            .is_some()
        {
            crossed += 1;
        }
        let _ = op.ws.close(None).await;
    }
    println!("200 hand-overs: {crossed} runs received a previous run's end");
    assert_eq!(crossed, 0);
}

/// With no command coming, feedback still arrives every 20 ms, as the
/// protocol page says.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn feedback_comes_every_20_ms() {
    let (_host, url) = start_host(&["--camera", "none"]);
    let mut watcher = Peer::connect(&url).await;
    watcher.hello("observer").await;
    let first = watcher.expect("feedback").await;
    let mut last = first.clone();
    for _ in 0..100 {
        last = watcher.expect("feedback").await;
    }
    let span = last["t_ms"].as_f64().unwrap() - first["t_ms"].as_f64().unwrap();
    let period = span / 100.0;
    println!("feedback every {period:.1} ms on average");
    assert!((18.0..=23.0).contains(&period), "{period:.1} ms");
}
