//! `vl lab check`: an experiment folder (an `experiment.toml` beside its
//! charts) through the thesis's pipeline, verified from outside as a lab
//! developer would: a sound folder passes, one whose chart can wedge the
//! session is refused with the firing sequence that does it, and bad
//! folders are refused naming the file and the line or the event; `vl lab
//! new` makes a folder that passes as made.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::common::{self, scratch, vl};

/// The shipped navigation experiment's folder.
const NAVIGATION: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/experiments/navigation");

/// A folder `id` under `root` holding the navigation lab's design as an
/// experiment folder, then changed by `change` (file name, old, new).
fn folder(root: &Path, id: &str, change: &[(&str, &str, &str)]) -> PathBuf {
    let dir = root.join(id);
    std::fs::create_dir_all(&dir).unwrap();
    for entry in std::fs::read_dir(NAVIGATION).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_owned();
        std::fs::copy(&path, dir.join(name)).unwrap();
    }
    for (file, old, new) in change {
        let path = dir.join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(old), "{file} has no {old:?}");
        std::fs::write(&path, text.replacen(old, new, 1)).unwrap();
    }
    dir
}

/// `vl lab check --json` on `folders`: its exit code and report.
fn check(folders: &[&Path]) -> (Option<i32>, Value) {
    let mut args = vec!["lab", "check", "--json"];
    args.extend(folders.iter().map(|f| common::s(f)));
    let out = vl(&args);
    let report = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("no report ({e}): {}", common::stderr(&out)));
    (out.status.code(), report)
}

#[test]
fn a_sound_folder_passes_and_one_that_can_wedge_is_refused_with_its_firing_sequence() {
    let root = scratch("lab-check-sound");
    let shuttle = folder(&root, "shuttle", &[]);
    let (code, report) = check(&[&shuttle]);
    assert_eq!(code, Some(0), "{report}");
    let shuttle_check = &report["folders"][0];
    assert_eq!(shuttle_check["id"], "shuttle");
    assert_eq!(shuttle_check["findings"], serde_json::json!([]));
    assert!(shuttle_check["markings"].as_u64().unwrap() > 1, "{report}");

    // A wheel may be lost while following (uncontrollable: no controller can
    // forbid it), and nothing leads out of that state.
    let wedged = folder(
        &root,
        "wedged",
        &[
            (
                "following.scxml",
                r#"    <transition event="release" target="still"/>
  </state>
</scxml>"#,
                r#"    <transition event="release" target="still"/>
    <transition event="wheel_lost" target="wedged"/>
  </state>
  <state id="wedged"/>
</scxml>"#,
            ),
            (
                "experiment.toml",
                r#""forecast_failed","#,
                r#""forecast_failed", "wheel_lost","#,
            ),
        ],
    );
    let (code, report) = check(&[&shuttle, &wedged]);
    assert_eq!(code, Some(1), "{report}");
    let findings = report["folders"][1]["findings"].as_array().unwrap();
    assert_eq!(findings.len(), 1, "{report}");
    let finding = findings[0].as_str().unwrap();
    assert!(finding.starts_with("no way back: after "), "{finding}");
    let sequence = finding
        .trim_start_matches("no way back: after ")
        .split(", ")
        .next()
        .unwrap();
    let events: Vec<&str> = sequence.split(" → ").collect();
    assert_eq!(events.last(), Some(&"wheel_lost"), "{finding}");
    assert!(events.contains(&"start"), "a run had started: {finding}");
    // The table says it too, for a person.
    let out = vl(&["lab", "check", common::s(&wedged)]);
    assert!(common::stdout(&out).contains("wedged: no way back: after "));
}

#[test]
fn bad_folders_are_refused_naming_the_file_and_the_line_or_the_event() {
    let root = scratch("lab-check-bad");
    let cases: Vec<(PathBuf, &str)> = vec![
        (
            folder(
                &root,
                "bad-toml",
                &[("experiment.toml", "title = ", "title = = ")],
            ),
            "bad-toml/experiment.toml: TOML parse error at line 4",
        ),
        (
            folder(
                &root,
                "no-chart",
                &[(
                    "experiment.toml",
                    r#""following"]"#,
                    r#""following", "docking"]"#,
                )],
            ),
            "no-chart/experiment.toml: chart 'docking': no docking.scxml beside it",
        ),
        (
            folder(
                &root,
                "bad-chart",
                &[(
                    "following.scxml",
                    r#"target="following""#,
                    r#"target="nowhere""#,
                )],
            ),
            "bad-chart/following.scxml: line 7: transition targets unknown state 'nowhere'",
        ),
        (
            folder(
                &root,
                "bad-rule",
                &[("experiment.toml", "then not start", "then not launch")],
            ),
            "no transition or event is called 'launch'",
        ),
        (
            folder(
                &root,
                "bad-event",
                &[(
                    "experiment.toml",
                    r#""forecast_failed","#,
                    r#""forecast_failed", "meteor","#,
                )],
            ),
            "uncontrollable event 'meteor' is no chart's",
        ),
        (
            folder(&root, "Not_An_Id", &[]),
            "'Not_An_Id' is no experiment id",
        ),
        (root.join("access"), "is the shipped access charts' folder"),
        (root.join("nothing-here"), "has no experiment.toml"),
        (huge(&root), "huge/following.scxml: larger than the 256 KiB"),
    ];
    for dir in ["access", "nothing-here"] {
        std::fs::create_dir_all(root.join(dir)).unwrap();
    }
    std::fs::write(
        root.join("access/experiment.toml"),
        "title = \"x\"\ncharts = []\n",
    )
    .unwrap();
    refused_as(&cases);
}

#[test]
fn a_new_folder_passes_the_check_as_made_and_is_never_made_over_another() {
    let root = scratch("lab-new");
    let out = vl(&["lab", "new", "shuttle", "--dir", common::s(&root)]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let made = root.join("shuttle");
    let toml = std::fs::read_to_string(made.join("experiment.toml")).unwrap();
    assert!(toml.contains("title = \"shuttle: "), "{toml}");
    let (code, report) = check(&[&made]);
    assert_eq!(code, Some(0), "{report}");
    assert_eq!(report["folders"][0]["id"], "shuttle");
    common::refused(
        &["lab", "new", "shuttle", "--dir", common::s(&root)],
        "is there already",
    );
    common::refused(
        &["lab", "new", "Shuttle", "--dir", common::s(&root)],
        "'Shuttle' is no experiment id",
    );
    assert!(!root.join("Shuttle").exists());
}

/// A folder with twenty-four switches nothing orders beside the navigation
/// charts: more markings than verifying may take.
fn vast(root: &Path) -> PathBuf {
    let switches: Vec<String> = (0..24).map(|i| format!("switch{i}")).collect();
    let quoted: Vec<String> = switches.iter().map(|c| format!("\"{c}\"")).collect();
    let vast = folder(
        root,
        "vast",
        &[(
            "experiment.toml",
            r#""following"]"#,
            &format!(r#""following", {}]"#, quoted.join(", ")),
        )],
    );
    for chart in &switches {
        let scxml = format!(
            "<scxml xmlns=\"http://www.w3.org/2005/07/scxml\" version=\"1.0\" name=\"{chart}\" initial=\"off\">\n\
             <state id=\"off\"><transition event=\"flip_{chart}\" target=\"on\"/></state>\n\
             <state id=\"on\"><transition event=\"flip_{chart}\" target=\"off\"/></state>\n</scxml>\n"
        );
        std::fs::write(vast.join(format!("{chart}.scxml")), scxml).unwrap();
    }
    vast
}

/// A folder whose chart is 50 MB: refused unread.
fn huge(root: &Path) -> PathBuf {
    let huge = folder(root, "huge", &[]);
    let chart = std::fs::File::create(huge.join("following.scxml")).unwrap();
    chart.set_len(50 << 20).unwrap();
    huge
}

/// Declarations vl cannot run: a definition kind it does not know, a chart
/// waiting for an event of a component the run lacks, more markings than
/// verifying may take.
#[test]
fn folders_declaring_what_vl_cannot_run_are_refused() {
    let root = scratch("lab-check-undeclared");
    let kind = [("experiment.toml", r#"kind = "path""#, r#"kind = "spline""#)];
    let run = [(
        "experiment.toml",
        r#"["plan", "forecast", "follow"]"#,
        r#"["plan", "follow"]"#,
    )];
    refused_as(&[
        (
            folder(&root, "bad-kind", &kind),
            "unknown variant `spline`, expected one of `goal`, `waypoints`, `path`, `obstacles`",
        ),
        (
            folder(&root, "no-forecast", &run),
            "a chart waits for 'forecast_passed', which only the component forecast fires",
        ),
        (vast(&root), "its state space is too large to verify"),
    ]);
}

/// `vl lab check` refuses every folder of `cases`, each saying its needle.
fn refused_as(cases: &[(PathBuf, &str)]) {
    let folders: Vec<&Path> = cases.iter().map(|(f, _)| f.as_path()).collect();
    let (code, report) = check(&folders);
    assert_eq!(code, Some(1), "{report}");
    for ((folder, needle), verdict) in cases.iter().zip(report["folders"].as_array().unwrap()) {
        let refused = verdict["refused"].as_str().unwrap_or_default();
        assert!(
            refused.contains(needle),
            "{}: {needle:?} not in {verdict}",
            folder.display()
        );
    }
}
