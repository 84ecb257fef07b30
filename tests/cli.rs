//! The `vl` binary as a newcomer meets it: its help, the headless demo and
//! its JSON report, and clear failures.

use crate::common;

use std::process::Command;

use common::{refused, stderr, stdout, vl};
use serde_json::Value;

#[test]
fn help_lists_the_subcommands_and_each_has_its_own() {
    let help = vl(&["--help"]);
    assert!(help.status.success());
    for sub in ["host", "guest", "demo"] {
        assert!(stdout(&help).contains(sub), "vl --help lacks {sub}");
        let own = vl(&[sub, "--help"]);
        assert!(own.status.success(), "vl {sub} --help failed");
        assert!(stdout(&own).contains("Usage: vl "), "{}", stdout(&own));
    }
}

#[test]
fn the_headless_demo_reaches_the_goal_and_reports_json() {
    let out = vl(&["demo", "--headless", "--json"]);
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status,
        stderr(&out)
    );
    let report: Value = serde_json::from_str(&stdout(&out)).expect("stdout is one JSON document");
    assert_eq!(report["reached_goal"], true);
    // The Host followed the path, steering from the camera's estimates.
    assert_eq!(report["pose_source"], "camera");
    let error = &report["path"]["path_error_mm"];
    assert!(error["max"].as_f64().unwrap() < 20.0, "{error}");
    assert!(report["planned"].as_array().unwrap().len() > 10);
    for key in ["x_mm", "y_mm", "theta_rad"] {
        assert!(report["final_pose"][key].is_f64(), "final_pose.{key}");
    }
    let goal = (680.0, 470.0);
    let (x, y) = (
        report["final_pose"]["x_mm"].as_f64().unwrap(),
        report["final_pose"]["y_mm"].as_f64().unwrap(),
    );
    assert!(
        (x - goal.0).hypot(y - goal.1) <= 15.0,
        "ended at ({x}, {y})"
    );
    assert!(report["sim_seconds"].as_f64().unwrap() > 0.0);
    let (p50, p99) = (
        &report["round_trip_ms"]["p50"],
        &report["round_trip_ms"]["p99"],
    );
    assert!(p50.as_f64().unwrap() > 0.0 && p99.as_f64().unwrap() >= p50.as_f64().unwrap());
}

#[test]
fn without_a_display_the_demo_says_so_and_runs_headless() {
    let out = vl(&["demo", "--timeout", "0.5"]);
    assert!(stderr(&out).contains("no display"), "{}", stderr(&out));
    // Half a second is too short to reach the goal: a clear failure, not a
    // hang; the run is stopped and its report still printed.
    assert!(!out.status.success());
    let said = stderr(&out);
    assert!(
        said.contains("did not reach the goal (stopped)") || said.contains("gave up waiting"),
        "{said}"
    );
}

#[test]
fn an_unreachable_host_is_a_clear_error_said_once() {
    let out = vl(&["guest", "--connect", "ws://127.0.0.1:9", "--headless"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let said = stderr(&out);
    assert!(
        said.contains("vl: cannot connect to ws://127.0.0.1:9: connection refused: is a vl Host listening there?"),
        "{said}"
    );
    // Tried again with back-off, each attempt shown, the error said once.
    assert!(said.contains("trying again"), "{said}");
    assert_eq!(said.matches("vl: cannot connect").count(), 1, "{said}");
}

#[test]
fn weak_error_lines_name_what_is_wrong_and_what_to_do() {
    refused(
        &["host", "--listen", "localhost"],
        "'localhost' is not an address and port: give 127.0.0.1:7400",
    );
    refused(
        &["media", "--listen", "localhost:7500"],
        "give 127.0.0.1:7500 for this machine only",
    );
    refused(
        &["media", "--profile", "nosuch.json"],
        "there is no file 'nosuch.json' (a link profile file",
    );
    // Something that answers HTTP is no vl Host: said at once, not retried.
    let web = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("ws://{}", web.local_addr().unwrap());
    std::thread::spawn(move || {
        use std::io::{Read, Write};
        for stream in web.incoming().flatten().take(4) {
            let mut stream = stream;
            let mut request = [0u8; 2048];
            let _ = stream.read(&mut request);
            let _ = stream.write_all(b"HTTP/1.0 200 OK\r\nContent-Length: 2\r\n\r\nhi");
        }
    });
    let out = vl(&["guest", "--connect", &url, "--headless"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("not a vl Host"), "{}", stderr(&out));
    assert!(!stderr(&out).contains("HTTP version"), "{}", stderr(&out));
}

#[test]
fn addresses_that_cannot_be_a_host_get_a_hint() {
    refused(
        &["guest", "--connect", "127.0.0.1:7400", "--headless"],
        "it has no scheme: try ws://127.0.0.1:7400",
    );
    refused(
        &["guest", "--connect", "wss://lab.example:7400/#pin=00"],
        "is not a SHA-256 fingerprint: 64 hex digits",
    );
}

#[test]
fn an_unknown_experiment_is_refused_with_the_known_ones() {
    refused(
        &["demo", "--headless", "--experiment", "juggling"],
        "invalid value 'juggling' for '--experiment <EXPERIMENT>'\n  [possible values: navigation, teleoperation, tour, your-controller]",
    );
    let help = stdout(&vl(&["host", "--help"]));
    assert!(
        help.contains("[possible values: navigation, teleoperation, tour, your-controller]"),
        "vl host --help names the experiments: {help}"
    );
}

#[test]
fn a_closed_pipe_ends_output_quietly() {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_vl"))
        .args(["sim", "link", "--profile", "lan", "--packets", "1000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Read nothing: close our end at once, as `| head -0` would.
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    child.wait().unwrap();
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_host_on_every_interface_prints_each_address_students_can_use() {
    use std::io::BufRead;
    let port = common::free_port();
    let mut child = common::vl_command()
        .args(["host", "--robot", "sim", "--no-record"])
        .args(["--listen", &format!("0.0.0.0:{port}")])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let lines: Vec<String> = std::io::BufReader::new(child.stderr.take().unwrap())
        .lines()
        .map_while(Result::ok)
        .take_while(|l| !l.contains("priority"))
        .collect();
    let _ = child.kill();
    let _ = child.wait();
    let text = lines.join("\n");
    assert!(
        text.contains(&format!("a firewall must let TCP port {port} in")),
        "{text}"
    );
    // Each address a Guest can dial (loopback last), never 0.0.0.0.
    let listed: Vec<&String> = lines.iter().filter(|l| l.contains("ws://")).collect();
    assert!(!listed.is_empty(), "{text}");
    assert!(
        listed
            .last()
            .unwrap()
            .contains(&format!("ws://127.0.0.1:{port}")),
        "{text}"
    );
    assert!(
        listed
            .iter()
            .all(|l| !l.contains("0.0.0.0") && l.contains("(browser: http://")),
        "{text}"
    );
}
