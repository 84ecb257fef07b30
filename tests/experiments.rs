//! Experiments as folders (the thesis's framework), from outside: the
//! tutorial in docs/experiments.md followed as written; a Host serving a
//! folder beside the shipped experiments, and refusing to start on one
//! that fails or takes a shipped id; the waypoint lab (`tour`), shipped as
//! a folder only, run to its end with its forecast, recording and grade;
//! and no Rust naming it.

use std::path::{Path, PathBuf};

use serde_json::Value;
use tokio::runtime::Runtime;

use crate::common::peer::Peer;
use crate::common::{self, s, scratch, start_host, start_vl_in, vl};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The ids a Host at `url` lists in its welcome.
fn offered(url: &str) -> Vec<String> {
    Runtime::new().unwrap().block_on(async {
        let mut peer = Peer::connect(url).await;
        let welcome = peer.hello("observer").await;
        welcome["experiments"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["id"].as_str().unwrap().to_owned())
            .collect()
    })
}

/// A command of the tutorial: its words, `vl` first.
fn words(line: &str) -> Vec<String> {
    line.split_whitespace().map(str::to_owned).collect()
}

/// docs/experiments.md, step by step in a fresh folder: each `sh` block's
/// `vl` lines run (`vl host` in the background on a free port, which the
/// Guest is pointed at), each `toml FILE` block appended to its file.
#[test]
fn the_tutorial_runs_as_written() {
    let dir = scratch("experiments-tutorial");
    let text = std::fs::read_to_string(repo().join("docs/experiments.md")).unwrap();
    let mut host = None;
    let mut ran = Vec::new();
    let mut block: Option<String> = None;
    for line in text.lines() {
        if let Some(kind) = &block {
            if line == "```" {
                block = None;
                continue;
            }
            if kind == "sh" && line.starts_with("vl ") {
                let args = words(line);
                let args: Vec<&str> = args[1..].iter().map(String::as_str).collect();
                ran.push(args[0].to_owned());
                match args[0] {
                    "host" => {
                        let args = [&["host", "--listen", "127.0.0.1:0"], &args[1..]].concat();
                        let (process, url) =
                            start_vl_in(Some(&dir), &args, "vl host listening on ");
                        assert_eq!(
                            offered(&url),
                            [
                                "navigation",
                                "teleoperation",
                                "tour",
                                "your-controller",
                                "shuttle"
                            ],
                            "the folder's beside the shipped"
                        );
                        host = Some((process, url));
                    }
                    "guest" => {
                        let url = &host.as_ref().expect("the tutorial serves it first").1;
                        let args = [&args[..], &["--connect", url, "--json"]].concat();
                        let out = command_in(&dir, &args);
                        let report: Value = serde_json::from_slice(&out.stdout)
                            .unwrap_or_else(|e| panic!("{e}: {}", common::stderr(&out)));
                        assert!(out.status.success(), "{}", common::stderr(&out));
                        assert_eq!(report["reached_goal"], true, "{report}");
                        assert_eq!(report["summary"]["experiment"], "shuttle", "{report}");
                    }
                    _ => {
                        let out = command_in(&dir, &args);
                        assert!(
                            out.status.success(),
                            "vl {args:?}: {}",
                            common::stderr(&out)
                        );
                        if args[..2] == ["lab", "check"] {
                            assert!(common::stdout(&out).contains("passes"));
                        }
                    }
                }
            } else if let Some(file) = kind.strip_prefix("toml ") {
                let path = dir.join(file);
                let mut was = std::fs::read_to_string(&path).unwrap();
                was.push_str(line);
                was.push('\n');
                std::fs::write(&path, was).unwrap();
            }
        } else if let Some(kind) = line.strip_prefix("```") {
            block = Some(kind.to_owned());
        }
    }
    assert_eq!(ran, ["lab", "lab", "host", "guest"], "every step ran");
    let design = std::fs::read_to_string(dir.join("labs/shuttle/experiment.toml")).unwrap();
    assert!(design.contains("time_s = 30"), "the rubric was added");
}

fn command_in(dir: &Path, args: &[&str]) -> std::process::Output {
    common::vl_command()
        .args(args)
        .current_dir(dir)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("vl runs")
}

/// `vl lab new ID` in `root`: the navigation experiment's design, to change.
fn new_folder(root: &Path, id: &str) -> PathBuf {
    let out = vl(&["lab", "new", id, "--dir", s(root)]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    root.join(id)
}

#[test]
fn a_host_serves_folders_beside_the_shipped_and_refuses_one_that_fails() {
    let root = scratch("experiments-served");
    let labs = root.join("labs");
    new_folder(&labs, "shuttle");
    new_folder(&labs, "ferry");
    let (_host, url) = start_host(&["--camera", "none", "--experiments", s(&labs)]);
    assert_eq!(
        offered(&url),
        [
            "navigation",
            "teleoperation",
            "tour",
            "your-controller",
            "ferry",
            "shuttle"
        ]
    );
    // Ids named: only those, a folder's among them.
    let only = format!("{},shuttle,navigation", labs.display());
    let (_host, url) = start_host(&["--camera", "none", "--experiments", &only]);
    assert_eq!(offered(&url), ["shuttle", "navigation"]);

    // A folder whose chart can wedge the session stops the Host before it
    // listens, naming the folder and the firing sequence.
    let broken = root.join("broken");
    let wedged = new_folder(&broken, "wedged");
    let chart = wedged.join("following.scxml");
    let text = std::fs::read_to_string(&chart).unwrap();
    let stuck = text
        .replacen(
            "<state id=\"following\">",
            "<state id=\"following\">\n    <transition event=\"finish\" target=\"stuck\"/>",
            1,
        )
        .replacen("</scxml>", "  <state id=\"stuck\"/>\n</scxml>", 1);
    assert_ne!(stuck, text);
    std::fs::write(&chart, stuck).unwrap();
    let out = vl(&["host", "--camera", "none", "--experiments", s(&broken)]);
    assert_eq!(out.status.code(), Some(2), "{}", common::stderr(&out));
    let said = common::stderr(&out);
    assert!(
        said.contains("--experiments") && said.contains("wedged"),
        "{said}"
    );
    assert!(said.contains(" → "), "the firing sequence: {said}");

    // A folder that takes a shipped id is refused, naming both.
    let clash = root.join("clash");
    new_folder(&clash, "navigation");
    let out = vl(&["host", "--camera", "none", "--experiments", s(&clash)]);
    assert_eq!(out.status.code(), Some(2), "{}", common::stderr(&out));
    let said = common::stderr(&out);
    assert!(
        said.contains(
            "its id 'navigation' is taken by the experiment of assets/experiments/navigation"
        ),
        "{said}"
    );
}

/// The waypoint lab, shipped as a folder: a headless run visits every
/// point in order without a contact, after its forecast, and is recorded
/// and graded by the folder's rubric as navigation's runs are.
#[test]
fn the_waypoint_lab_visits_every_point_in_order_and_is_graded_on_them() {
    let dir = scratch("experiments-waypoints");
    let (_host, url) = start_host(&["--camera", "sim"]);
    let out = vl(&[
        "guest",
        "--connect",
        &url,
        "--headless",
        "--json",
        "--experiment",
        "tour",
        "--waypoints",
        "150,320;400,330;680,470",
        "--download-to",
        s(&dir),
        "--timeout",
        "90",
    ]);
    let report: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", common::stderr(&out)));
    assert!(out.status.success(), "{report}");
    let summary = &report["summary"];
    assert_eq!(summary["experiment"], "tour");
    assert_eq!(summary["reason"], "goal_reached", "{summary}");
    assert_eq!(summary["waypoints"]["visited"], 3, "{summary}");
    assert_eq!(summary["waypoints"]["of"], 3);
    assert_eq!(summary["collisions"], 0);
    assert!(
        report["forecast"].is_object(),
        "tried on the twin: {report}"
    );
    let recording = PathBuf::from(report["downloaded"].as_str().expect("recorded"));
    assert!(recording.metadata().unwrap().len() > 10_000);

    // Graded by the folder's rubric: the points, the time, the tracking.
    let summary: vl_core::Summary = serde_json::from_value(summary.clone()).unwrap();
    let design = vl_core::LabDesign::from_folder(&repo().join("assets/experiments/tour")).unwrap();
    let rubric = design
        .experiment
        .unwrap()
        .rubric
        .expect("the folder's rubric");
    let grade = rubric.grade(&summary);
    let line = |name: &str| grade.lines.iter().find(|l| l.criterion == name).unwrap();
    assert_eq!(line("waypoints").points, 50.0, "{}", grade.comment());
    assert!(line("time").points > 0.0, "{}", grade.comment());
    assert!(grade.given > 60.0, "{}", grade.comment());

    // Fewer points than it visits are refused, saying how many it takes.
    let out = vl(&[
        "guest",
        "--connect",
        &url,
        "--headless",
        "--experiment",
        "tour",
        "--waypoints",
        "680,470",
    ]);
    assert!(!out.status.success());
    let said = common::stderr(&out);
    assert!(
        said.contains("visits 2 to 8 waypoints, and the definition has 1"),
        "{said}"
    );
}

/// Every shipped folder passes `vl lab check`; the waypoint lab's id is no
/// string in vl's Rust: it is a folder only.
#[test]
fn the_shipped_folders_pass_and_no_rust_names_the_waypoint_lab() {
    let shipped: Vec<PathBuf> = std::fs::read_dir(repo().join("assets/experiments"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(shipped.len(), 4, "{shipped:?}");
    let mut args = vec!["lab", "check", "--json"];
    args.extend(shipped.iter().map(|p| s(p)));
    let out = vl(&args);
    assert!(out.status.success(), "{}", common::stdout(&out));

    let mut named = Vec::new();
    for top in ["crates", "src"] {
        rust_files(&repo().join(top), &mut |file, text| {
            if text.contains("\"tour\"") || text.contains("\"tour/") {
                named.push(file.display().to_string());
            }
        });
    }
    assert!(named.is_empty(), "Rust names the waypoint lab: {named:?}");
}

/// Calls `each` with every `.rs` file under `dir` and its text.
fn rust_files(dir: &Path, each: &mut dyn FnMut(&Path, &str)) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, each);
        } else if path.extension().is_some_and(|e| e == "rs") {
            each(&path, &std::fs::read_to_string(&path).unwrap());
        }
    }
}

/// `vl experiment run` takes any experiment by id: the waypoint lab (its
/// points, when none are given, the fewest it visits along the way to the
/// arena's goal) and a folder's, served beside the shipped ones.
#[test]
fn experiment_run_takes_a_folder_s_experiment_and_the_waypoint_lab() {
    let root = scratch("experiments-run");
    new_folder(&root.join("labs"), "ferry");
    let labs = root.join("labs");
    for args in [
        vec!["experiment", "run", "tour", "--json"],
        vec![
            "experiment",
            "run",
            "ferry",
            "--experiments",
            s(&labs),
            "--json",
        ],
    ] {
        let report = common::vl_json(&args);
        assert_eq!(report["all_succeeded"], true, "{args:?}: {report}");
        let run = &report["runs"][0];
        assert_eq!(run["experiment"], args[2], "{report}");
    }
    common::refused(
        &["experiment", "run", "ferry"],
        "unknown experiment 'ferry' (known: navigation, teleoperation, tour, your-controller)",
    );
}

/// A folder written from scratch, from the shared charts alone: a run that
/// holds the robot still for at most two seconds. Its commands are refused,
/// its unset time limit is the most it allows, and the robot does not move.
#[test]
fn a_run_that_holds_the_robot_still_is_composed_from_the_shared_charts() {
    let labs = scratch("experiments-hold").join("labs");
    let still = labs.join("still");
    std::fs::create_dir_all(&still).unwrap();
    std::fs::write(
        still.join("experiment.toml"),
        r#"title = "Hold still"
help = "The robot stays where it is for the run."
charts = ["mount", "define", "execute", "cspace"]
uncontrollable = ["finish", "release", "cspace_built"]

[[define]]
kind = "number"
setting = "time_limit_s"
min = 0.5
max = 2

[run]
components = ["hold"]

[[controller]]
why = "a run starts only on a mounted experiment"
rule = "if mount.idle then not start"
"#,
    )
    .unwrap();
    let out = vl(&["lab", "check", s(&still)]);
    assert!(out.status.success(), "{}", common::stdout(&out));
    let (_host, url) = start_host(&["--camera", "sim", "--no-record", "--experiments", s(&labs)]);
    let report = common::vl_json(&[
        "guest",
        "--connect",
        &url,
        "--headless",
        "--json",
        "--experiment",
        "still",
    ]);
    let summary = &report["summary"];
    assert_eq!(summary["reason"], "time_limit", "{summary}");
    // Ended by the limit it was given (the most the folder allows), not a
    // fixed bound on how late: the reason says the limit took effect.
    assert!(summary["seconds"].as_f64().unwrap() >= 2.0, "{summary}");
    assert!(summary["distance_mm"].as_f64().unwrap() < 1.0, "{summary}");
    Runtime::new().unwrap().block_on(async {
        let mut op = Peer::connect(&url).await;
        op.hello("operator").await;
        op.send(serde_json::json!({"type": "mount", "experiment": "still"}))
            .await;
        op.expect("mounted").await;
        op.send(serde_json::json!({"type": "start"})).await;
        op.expect("started").await;
        op.send(serde_json::json!({"type": "command", "event": 1, "v": 100.0, "w": 0.0}))
            .await;
        let refused = op.expect("error").await;
        assert!(
            refused["message"]
                .as_str()
                .unwrap()
                .contains("holds the robot still"),
            "{refused}"
        );
    });
}
