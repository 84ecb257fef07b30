//! The thesis's chapter 7 through the CLI: every link profile through the
//! Media, event-based against time-based control, both experiments
//! (`vl experiment report`), and one run's JSON (`vl experiment run`).

use crate::common;

use common::{s, scratch, vl};
use serde_json::Value;

#[test]
fn the_matrix_keeps_event_based_runs_synchronised_and_writes_its_report() {
    let dir = scratch("experiment-report");
    let out = vl(&[
        "experiment",
        "report",
        "--out",
        s(&dir),
        "--seeds",
        "1",
        "--jobs",
        "4",
        // Slow on a busy machine is not stuck (118 s of 120 seen once).
        "--timeout=400",
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("[18/18]"), "progress is shown: {stderr}");
    let summary: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(summary["event_based_synchronised"], true);
    assert_eq!(summary["collisions"], 0);
    let runs = summary["runs"].as_array().unwrap();
    assert_eq!(
        runs.len(),
        18,
        "6 profiles × navigation, teleoperation event, teleoperation time"
    );
    for run in runs {
        assert_eq!(run["reached_goal"], true, "{run}");
        for field in [
            "max_event_gap",
            "sync_violations",
            "collisions",
            "completion_s",
        ] {
            assert!(run[field].is_number(), "{field}: {run}");
        }
        for field in ["tracking_error_mm", "prediction_error_mm"] {
            assert!(
                run[field]["mean"].is_number() && run[field]["max"].is_number(),
                "{field}: {run}"
            );
        }
        let legs = &run["delays"];
        assert!(legs["guest_to_host"]["p99"].is_number(), "{run}");
        assert!(legs["host_to_guest"]["p50"].is_number(), "{run}");
        if run["pacing"] == "event" {
            assert!(run["max_event_gap"].as_u64() <= Some(1), "{run}");
            assert_eq!(run["sync_violations"], 0, "{run}");
        }
    }
    // Commands every 20 ms over a 150 ms round trip run ahead of their feedback.
    let time_based = runs
        .iter()
        .find(|r| {
            r["profile"] == "intercontinental"
                && r["pacing"] == "time"
                && r["experiment"] == "teleoperation"
        })
        .unwrap();
    assert!(
        time_based["max_event_gap"].as_u64().unwrap() > 1,
        "{time_based}"
    );
    // The ghost is closer to where the robot was than the delayed pose shown beside it.
    let event = runs
        .iter()
        .find(|r| {
            r["profile"] == "geo-satellite"
                && r["pacing"] == "event"
                && r["experiment"] == "teleoperation"
        })
        .unwrap();
    assert!(
        event["prediction_error_mm"]["mean"].as_f64() < event["stale_error_mm"]["mean"].as_f64(),
        "{event}"
    );
    let report = std::fs::read_to_string(dir.join("report.md")).unwrap();
    for needle in [
        "## Outcomes",
        "## Figures",
        "## Against the thesis",
        "| experiment | profile | pacing |",
        "## Time analysis",
        "tracking-by-profile.png",
        "sync-geo-satellite.png",
        "delays-congested.png",
        "paths-lan.png",
        "prediction-by-profile.png",
    ] {
        assert!(report.contains(needle), "report.md lacks {needle}");
    }
    for picture in [
        "tracking-by-profile.png",
        "tracking-by-profile.svg",
        "delays-lan.png",
        "sync-lan.svg",
    ] {
        let bytes = std::fs::read(dir.join(picture)).unwrap();
        assert!(bytes.len() > 1000, "{picture} is drawn");
    }
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), 18);
}

/// The experiments have one name each, everywhere; the names
/// `vl experiment run` once had of its own are refused with the new one.
#[test]
fn the_old_experiment_names_are_refused_with_the_new() {
    common::refused(
        &["experiment", "run", "mobile"],
        "'mobile' is called 'navigation' now",
    );
    common::refused(
        &["experiment", "run", "teleop"],
        "'teleop' is called 'teleoperation' now",
    );
}

#[test]
fn a_bad_profile_is_named() {
    common::refused(
        &[
            "experiment",
            "run",
            "teleoperation",
            "--profile",
            "carrier-pigeon",
        ],
        "'carrier-pigeon' is neither a link profile",
    );
}

/// Runs that fail are named with why they ended, in the report and on the
/// console, and kept out of the figures; no log line's colour codes leak.
#[test]
fn failed_runs_are_listed_with_their_reason() {
    let dir = scratch("experiment-report-failed");
    let out = vl(&[
        "experiment",
        "report",
        "--out",
        s(&dir),
        "--profiles",
        "lan",
        "--seeds",
        "1",
        // Long enough for the definition's forecast on a loaded machine,
        // too short for the runs.
        "--timeout",
        "2",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stdout.contains("failed: navigation on lan"), "{stdout}");
    assert!(stdout.contains("left out of the figures"), "{stdout}");
    assert!(
        !stderr.contains('\u{1b}'),
        "colour codes in a log: {stderr}"
    );
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("### Runs that failed"), "{md}");
    assert!(md.contains("| stopped") || md.contains("stopped"), "{md}");
}

/// Several seeds a cell: every figure is a mean with its 95 % interval, in
/// Markdown tables, and the report says where the runs agree with the
/// thesis and where not. (One profile here; README's command runs them all
/// at five seeds, which takes minutes.)
#[test]
fn the_report_gives_each_figure_its_interval_in_markdown_tables() {
    let dir = scratch("experiment-report-intervals");
    let out = vl(&[
        "experiment",
        "report",
        "--out",
        s(&dir),
        "--profiles",
        "lan",
        "--seeds",
        "3",
        "--jobs",
        "3",
    ]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(
        !md.contains("```"),
        "tables are Markdown, not text blocks:\n{md}"
    );
    let figures = md
        .lines()
        .skip_while(|l| !l.starts_with("## Figures"))
        .find(|l| l.starts_with("| teleoperation | lan | event |"))
        .unwrap_or_else(|| panic!("no teleoperation row:\n{md}"));
    let cells: Vec<&str> = figures.split('|').map(str::trim).collect();
    assert_eq!(cells[4], "3", "three seeds: {figures}");
    assert!(
        cells[5].contains(" ± "),
        "tracking with its interval: {figures}"
    );
    assert!(
        md.contains("|:--|:--|:--|--:|"),
        "words left, figures right:\n{md}"
    );
    assert!(md.contains("**Synchronisation — agrees.**"), "{md}");
    assert!(md.contains("**Why.**"), "{md}");
}
