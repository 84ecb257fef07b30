//! `vl khepera-emu` spoken to through `serialport` on its pseudo-terminal,
//! as the Host's serial driver and K-Team's own tools would.

use crate::common;

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use common::{start_emulator, start_emulator_watched, start_khepera_host_with};

use serialport::SerialPort;

fn open(device: &str) -> Box<dyn SerialPort> {
    serialport::new(device, 38_400)
        .stop_bits(serialport::StopBits::Two)
        .timeout(Duration::from_secs(2))
        .open()
        .unwrap_or_else(|e| panic!("cannot open {device}: {e}"))
}

/// Sends one command and reads its CRLF-terminated reply.
fn ask(port: &mut Box<dyn SerialPort>, command: &str) -> String {
    port.write_all(format!("{command}\r").as_bytes()).unwrap();
    let mut reply = Vec::new();
    let mut byte = [0u8; 1];
    while !reply.ends_with(b"\r\n") {
        port.read_exact(&mut byte)
            .unwrap_or_else(|e| panic!("no reply to {command}: {e}"));
        reply.push(byte[0]);
    }
    String::from_utf8(reply).unwrap().trim_end().to_owned()
}

fn numbers(reply: &str) -> Vec<i64> {
    reply
        .split(',')
        .skip(1)
        .map(|v| v.parse().unwrap())
        .collect()
}

#[test]
fn the_emulated_khepera_answers_on_its_serial_line() {
    let link = std::env::temp_dir().join(format!("vl-khepera-{}", std::process::id()));
    let (_emu, device) = start_emulator(&["--link", link.to_str().unwrap()]);
    assert!(device.starts_with("/dev/pts/"), "{device}");
    assert_eq!(std::fs::read_link(&link).unwrap().to_str().unwrap(), device);

    let mut port = open(link.to_str().unwrap());
    assert_eq!(ask(&mut port, "B"), "b,5.02,5.01");
    assert_eq!(ask(&mut port, "X"), "z,Command not found");
    assert_eq!(ask(&mut port, "G,0,0"), "g");

    // Far from everything, the proximity sensors read only noise.
    let far = numbers(&ask(&mut port, "N"));
    assert_eq!(far.len(), 8);
    assert!(far.iter().all(|v| (0..=1023).contains(v)));

    // At D,10,10 the counters grow by 10 pulses per 10 ms. The counters
    // were read at some moment within each exchange: the time between the
    // two readings lies between the inner and the outer ends of the
    // exchanges, however this machine schedules the test.
    assert_eq!(ask(&mut port, "D,10,10"), "d");
    std::thread::sleep(Duration::from_millis(200));
    let asked0 = Instant::now();
    let h0 = numbers(&ask(&mut port, "H"));
    let answered0 = Instant::now();
    std::thread::sleep(Duration::from_millis(500));
    let asked1 = Instant::now();
    let h1 = numbers(&ask(&mut port, "H"));
    let answered1 = Instant::now();
    let ticks = |d: Duration| d.as_secs_f64() / 0.01;
    let (least, most) = (ticks(asked1 - answered0), ticks(answered1 - asked0));
    for wheel in 0..2 {
        let grew = (h1[wheel] - h0[wheel]) as f64;
        assert!(
            grew >= 0.95 * 10.0 * least && grew <= 1.05 * 10.0 * most,
            "wheel {wheel}: {grew} pulses in {least:.1} to {most:.1} ticks of 10 ms"
        );
    }

    // Driving on toward the box ahead, the front sensors rise.
    assert_eq!(ask(&mut port, "D,40,40"), "d");
    std::thread::sleep(Duration::from_millis(600));
    let near = numbers(&ask(&mut port, "N"));
    assert!(
        near[2] > far[2] + 200 && near[3] > far[3] + 200,
        "far {far:?}, near {near:?}"
    );
    assert_eq!(ask(&mut port, "D,0,0"), "d");

    // Closing and reopening the port works; the robot's state survives.
    drop(port);
    let mut port = open(&device);
    assert_eq!(ask(&mut port, "B"), "b,5.02,5.01");
    let h2 = numbers(&ask(&mut port, "H"));
    assert!(h2[0] > h1[0]);
    let _ = std::fs::remove_file(&link);
}

#[test]
fn line_timing_takes_as_long_as_the_baud_rate_says() {
    let (_emu, device) = start_emulator(&["--baud", "9600"]);
    let mut port = open(&device);
    let started = Instant::now();
    let reply = ask(&mut port, "N");
    let took = started.elapsed().as_secs_f64();
    // 11 bits per character at 9600 baud.
    let expected = (reply.len() + 2) as f64 * 11.0 / 9600.0;
    assert!(
        took >= expected * 0.9,
        "{took:.3} s for {} characters",
        reply.len() + 2
    );
    // The old instant line, asked for by name, answers in less.
    let (_emu, device) = start_emulator(&["--baud", "9600", "--instant-line"]);
    let mut port = open(&device);
    let started = Instant::now();
    ask(&mut port, "N");
    let instant = started.elapsed().as_secs_f64();
    assert!(
        instant < took,
        "{instant:.3} s on an instant line, {took:.3} s at 9600 baud"
    );
}

/// `vl khepera characterise` through the Host's serial driver against the
/// emulator, whose speed controller is known (gain 1, 30 ms, 4 m/s²):
/// the fit recovers it, and the model file it writes drives the simulator.
#[test]
fn characterising_the_emulator_recovers_its_speed_response() {
    let (_emu, device) = start_emulator(&["--arena", "open"]);
    let dir = common::scratch("characterise");
    let file = dir.join("model.json");
    let report = common::vl_json(&[
        "khepera",
        "characterise",
        "--port",
        &device,
        "-o",
        common::s(&file),
        "--json",
    ]);
    let r = &report["fit"]["response"];
    let truth = vl_core::SpeedResponse::default();
    let (gain, tau, accel) = (
        r["gain"].as_f64().unwrap(),
        r["time_constant_s"].as_f64().unwrap(),
        r["max_accel_mm_s2"].as_f64().unwrap(),
    );
    println!(
        "gain {gain:.3}, time constant {:.1} ms, acceleration {accel:.0} mm/s², dead time {:.1} ms",
        tau * 1e3,
        r["dead_time_s"].as_f64().unwrap() * 1e3
    );
    assert!((gain - truth.gain).abs() <= 0.05 * truth.gain, "{report}");
    assert!(
        (tau - truth.time_constant_s).abs() <= 0.05 * truth.time_constant_s,
        "{report}"
    );
    assert!(
        (accel - truth.max_accel_mm_s2).abs() <= 0.1 * truth.max_accel_mm_s2,
        "{report}"
    );
    let model = vl_core::RobotModel::from_json(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(model.response.time_constant_s, tau);
    let run = common::vl_json(&["sim", "run", "--robot-model", common::s(&file), "--json"]);
    assert_eq!(run["following"]["reached_goal"], true, "{run}");
}

/// The navigation experiment on the emulated Khepera with no camera, in
/// `arena`: the Host's pose comes from odometry and the IR sensors against
/// the map alone. The emulator's own truth judges the run: no contact, and
/// the robot truly at the goal.
fn navigation_without_a_camera(arena: &str) {
    let (_emulator, device, truth) = start_emulator_watched(&["--arena", arena]);
    let (_host, url) = start_khepera_host_with(&device, &["--arena", arena, "--no-reset"]);
    let summary = common::headless_run(&url, 60, &[]);
    assert_eq!(summary["reason"], "goal_reached", "{arena}: {summary}");
    assert_eq!(summary["collisions"], 0, "{arena}: {summary}");
    assert_eq!(summary["pose_source"], "odometry", "{arena}: {summary}");
    // The emulator says where the robot truly is 20 times a second: wait
    // for a line from after the run.
    std::thread::sleep(Duration::from_millis(700));
    let last = truth
        .try_iter()
        .filter(|l| l.starts_with("truth "))
        .last()
        .expect("the emulator told its truth");
    let f: Vec<f64> = last
        .split(' ')
        .skip(1)
        .map(|v| v.parse().expect("a number"))
        .collect();
    assert_eq!(f[4], 0.0, "{arena}: the robot touched something: {last}");
    let goal = vl_core::Arena::named(arena)
        .and_then(|a| a.goal)
        .expect("a shipped arena has a goal");
    let off = (f[1] - goal.x_mm).hypot(f[2] - goal.y_mm);
    eprintln!("{arena}: truly {off:.1} mm from the goal ({last})");
    // The run ends within the goal's tolerance by the estimate; the truth
    // may lie a few millimetres further.
    assert!(
        off < 25.0,
        "{arena}: truly {off:.1} mm from the goal: {last}"
    );
}

#[test]
fn without_a_camera_the_navigation_run_finishes_in_every_shipped_arena() {
    for arena in vl_core::Arena::shipped() {
        navigation_without_a_camera(arena);
    }
}

#[test]
fn a_run_too_uncertain_to_go_on_says_why_in_words() {
    // A robot whose odometry slips this much, and whose sensors the Host
    // believes see nothing beyond a millimetre, cannot pass the navigation
    // arena's gaps on dead reckoning: the run must end, saying so.
    let dir = common::scratch("too-uncertain");
    let model = dir.join("slippery.json");
    let slippery = vl_core::RobotModel {
        wheel_slip: 0.4,
        sensor_range_mm: 1.0,
        ..vl_core::RobotModel::khepera_ii()
    };
    std::fs::write(&model, serde_json::to_string(&slippery).unwrap()).unwrap();
    let (_emulator, device) = start_emulator(&[]);
    let (_host, url) = start_khepera_host_with(&device, &["--robot-model", common::s(&model)]);
    let out = common::vl(&["guest", "--connect", &url, "--headless", "--timeout", "60"]);
    let (stdout, stderr) = (common::stdout(&out), common::stderr(&out));
    assert_eq!(out.status.code(), Some(1), "{stdout}{stderr}");
    assert!(
        stdout.contains("held back by the safety layer: position uncertain by"),
        "{stdout}"
    );
    assert!(
        stderr.contains("add a camera or widen the margin"),
        "{stderr}"
    );
}
