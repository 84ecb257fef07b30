//! `vl petri` through its command line: the thesis's methodology end to end
//! (statecharts → nets → composition → analysis → controller), and clear
//! refusals of bad input with exit code 2.

use crate::common;

use common::{refused, s, scratch, stdout, vl, vl_json as ok_json};
use serde_json::Value;

fn example(name: &str) -> String {
    format!("{}/examples/statecharts/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The composed lab's analysis, as the thesis reads it: six states, safe,
/// live, reversible, conservative, with every figure in the JSON.
fn analyzed_as_the_thesis_says(lab: &std::path::Path) -> serde_json::Value {
    let a = ok_json(&["petri", "analyze", "--json", s(lab)]);
    assert_eq!(a["states"], 6);
    assert_eq!(a["bounded"], true);
    assert_eq!(a["safe"], true);
    assert_eq!(a["deadlock"], false);
    assert_eq!(a["live"], true, "the experiment can always proceed");
    assert_eq!(a["reversible"], true, "the lab can always return to idle");
    assert_eq!(a["conservative"], true);
    for key in [
        "places",
        "transitions",
        "edges",
        "max_tokens_in_place",
        "max_tokens_per_marking",
        "deadlock_trace",
        "quasi_live",
        "p_flow_basis_dim",
        "t_flow_basis_dim",
        "seconds",
        "peak_heap_bytes",
        "peak_resident_bytes",
    ] {
        assert!(a.get(key).is_some(), "analyze --json lacks {key}");
    }
    a
}

#[test]
fn statecharts_to_a_controlled_lab_net() {
    let dir = scratch("methodology");
    let (mount, execute, lab, controlled) = (
        dir.join("mount.pnml"),
        dir.join("execute.pnml"),
        dir.join("lab.pnml"),
        dir.join("controlled.pnml"),
    );
    assert!(
        vl(&[
            "petri",
            "from-scxml",
            &example("mount.scxml"),
            "-o",
            s(&mount)
        ])
        .status
        .success()
    );
    assert!(
        vl(&[
            "petri",
            "from-scxml",
            &example("execute.scxml"),
            "-o",
            s(&execute)
        ])
        .status
        .success()
    );
    assert!(
        vl(&[
            "petri",
            "compose",
            s(&mount),
            s(&execute),
            "-o",
            s(&lab),
            "--fuse-parallel-places"
        ])
        .status
        .success()
    );

    let a = analyzed_as_the_thesis_says(&lab);
    // Forbid starting a run while the robot's last command is unanswered, and
    // limit the lab to one defined experiment at a time.
    let out = vl(&[
        "petri",
        "control",
        s(&lab),
        "--constraint",
        "if execute.executed then not execute.t5_ready_start",
        "--constraint",
        "execute.ready + execute.running <= 1",
        "-o",
        s(&controlled),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("monitor place monitor2"), "{said}");
    assert!(
        said.contains("inhibitor arc execute.executed ⊸ execute.t5_ready_start"),
        "{said}"
    );
    let c = ok_json(&["petri", "analyze", "--json", s(&controlled)]);
    assert_eq!(
        c["places"],
        a["places"].as_u64().unwrap() + 1,
        "one monitor place added"
    );
    assert_eq!(c["deadlock"], false);

    // People read the same analysis as a table, in words that agree in number.
    let table = stdout(&vl(&["petri", "analyze", s(&lab)]));
    assert!(
        table.contains("yes (at most 1 token in a place, 3 tokens in a marking)"),
        "{table}"
    );

    let inv = ok_json(&["petri", "invariants", "--json", s(&lab)]);
    assert!(!inv["p_invariants"].as_array().unwrap().is_empty());
    let dot = vl(&["petri", "dot", s(&controlled)]);
    assert!(String::from_utf8_lossy(&dot.stdout).starts_with("digraph"));
    let rg = vl(&["petri", "dot", "--reachability", s(&lab)]);
    assert_eq!(
        String::from_utf8_lossy(&rg.stdout)
            .matches("[shape=box")
            .count(),
        6
    );
}

#[test]
fn unbounded_nets_are_reported_as_such() {
    let dir = scratch("unbounded");
    let net = dir.join("producer.pnml");
    std::fs::write(&net, PRODUCER).unwrap();
    let a = ok_json(&["petri", "analyze", "--json", s(&net)]);
    assert_eq!(a["bounded"], false);
    assert_eq!(a["states"], Value::Null);
    let dot = dir.join("cov.dot");
    let c = ok_json(&["petri", "coverability", "--json", s(&net), "--dot", s(&dot)]);
    assert_eq!(c["bounded"], false);
    assert_eq!(c["unbounded_places"], serde_json::json!(["buffer"]));
    assert_eq!(
        c["maximal"],
        serde_json::json!([{"ready": 1, "buffer": "ω"}])
    );
    assert!(std::fs::read_to_string(&dot).unwrap().contains("buffer:ω"));
    // Counting states alone has no Karp–Miller shortcut: it stops at the
    // limit and says how to go on.
    let out = vl(&["petri", "states", "--max-states", "500", s(&net)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("stopped at the limit of 500 states") && err.contains("raise --max-states"),
        "{err}"
    );
}

/// The shipped examples are built in: named, they are found from any
/// directory.
#[test]
fn shipped_examples_are_found_by_name_anywhere() {
    let c = ok_json(&["petri", "coverability", "--json", "producer-consumer"]);
    assert_eq!(c["unbounded_places"], serde_json::json!(["buffer"]));
    let dir = scratch("elsewhere");
    let out = dir.join("mount.pnml");
    let made = common::vl_command()
        .current_dir(&dir)
        .args([
            "petri",
            "from-scxml",
            "examples/statecharts/mount.scxml",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", common::stderr(&made));
    let pnml = std::fs::read_to_string(&out).unwrap();
    assert!(pnml.contains("<pnml"));
    // By its file name or its stem too, and the large corpus models by
    // their path in the repository; anything else names the examples.
    let run = |args: &[&str]| {
        common::vl_command()
            .current_dir(&dir)
            .args(args)
            .output()
            .unwrap()
    };
    for name in ["mount.scxml", "mount"] {
        let again = dir.join(format!("{name}.pnml"));
        let made = run(&["petri", "from-scxml", name, "-o", s(&again)]);
        assert!(made.status.success(), "{name}: {}", common::stderr(&made));
        assert_eq!(std::fs::read_to_string(&again).unwrap(), pnml, "{name}");
    }
    let kanban = "assets/petri-corpus/core/Kanban-PT-00005/model.pnml";
    let states = run(&["petri", "dot", kanban]);
    assert!(states.status.success(), "{}", common::stderr(&states));
    let missing = run(&["petri", "analyze", "model.pnml"]);
    assert_eq!(missing.status.code(), Some(2));
    let e = common::stderr(&missing);
    assert!(e.contains("cannot read model.pnml: "), "{e}");
    assert!(
        e.contains("shipped examples: examples/statecharts/mount.scxml"),
        "{e}"
    );
}

const PRODUCER: &str = r#"<?xml version="1.0"?>
<pnml xmlns="http://www.pnml.org/version-2009/grammar/pnml">
 <net id="producer" type="http://www.pnml.org/version-2009/grammar/ptnet"><page id="pg">
  <place id="ready"><initialMarking><text>1</text></initialMarking></place>
  <place id="buffer"/>
  <transition id="produce"/>
  <arc id="a1" source="ready" target="produce"/>
  <arc id="a2" source="produce" target="ready"/>
  <arc id="a3" source="produce" target="buffer"><inscription><text>2</text></inscription></arc>
 </page></net></pnml>"#;

#[test]
fn bad_input_is_refused_with_exit_code_2() {
    let dir = scratch("bad");
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let truncated = write("truncated.pnml", &PRODUCER[..PRODUCER.len() / 2]);
    refused(&["petri", "analyze", s(&truncated)], "not well-formed XML");
    refused(&["petri", "states", s(&truncated)], "not well-formed XML");
    refused(
        &["petri", "states", "--threads", "0", s(&truncated)],
        "--threads",
    );
    let missing = write(
        "missing.pnml",
        &PRODUCER.replace(r#"target="buffer""#, r#"target="nowhere""#),
    );
    refused(
        &["petri", "analyze", s(&missing)],
        "line 9: arc 'a3' refers to missing node 'nowhere'",
    );
    let negative = write(
        "negative.pnml",
        &PRODUCER.replace("<text>2</text>", "<text>-2</text>"),
    );
    refused(
        &["petri", "invariants", s(&negative)],
        "arc weight -2 is negative",
    );
    let good = write("producer.pnml", PRODUCER);
    let out = dir.join("out.pnml");
    refused(
        &[
            "petri",
            "control",
            s(&good),
            "--constraint",
            "ready + ghost <= 1",
            "-o",
            s(&out),
        ],
        "names unknown place 'ghost'",
    );
    refused(
        &[
            "petri",
            "control",
            s(&good),
            "--constraint",
            "ready < 1",
            "-o",
            s(&out),
        ],
        "does not parse",
    );
    refused(
        &["petri", "analyze", s(&dir.join("absent.pnml"))],
        "cannot read",
    );
    let chart = write(
        "broken.scxml",
        "<scxml><state id=\"a\"><transition target=\"b\"/></state></scxml>",
    );
    refused(
        &["petri", "from-scxml", s(&chart), "-o", s(&out)],
        "unknown state 'b'",
    );
    let inhibited = write("inhibited.pnml", &PRODUCER.replace(
        r#"<arc id="a3" source="produce" target="buffer">"#,
        r#"<arc id="a4" source="buffer" target="produce"><type value="inhibitor"/></arc><arc id="a3" source="produce" target="buffer">"#,
    ));
    refused(
        &["petri", "coverability", s(&inhibited)],
        "unsound with inhibitor arcs",
    );
}

/// Files made to hurt: states nested 40,000 deep are refused naming the
/// limit, and a net of 10,000 places and one transition is analysed in
/// memory that grows with the net, not with its square (it took 681 MB).
#[test]
fn deep_charts_are_refused_and_wide_nets_stay_small() {
    let dir = scratch("hostile-files");
    let deep = dir.join("deep.scxml");
    let depth = 40_000;
    let chart = format!(
        "<scxml xmlns=\"http://www.w3.org/2005/07/scxml\" version=\"1.0\">{}{}</scxml>",
        (0..depth)
            .map(|i| format!("<state id=\"s{i}\">"))
            .collect::<String>(),
        "</state>".repeat(depth)
    );
    std::fs::write(&deep, chart).unwrap();
    let out = dir.join("deep.pnml");
    refused(
        &["petri", "from-scxml", s(&deep), "-o", s(&out)],
        "states nest more than 64 deep",
    );

    let wide = dir.join("wide.pnml");
    let places = 10_000;
    let mut net = String::from(
        "<?xml version=\"1.0\"?><pnml><net id=\"wide\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"g\">",
    );
    for i in 0..places {
        net +=
            &format!("<place id=\"p{i}\"><initialMarking><text>1</text></initialMarking></place>");
    }
    net += "<transition id=\"t\"/>";
    for i in 0..places {
        net += &format!("<arc id=\"a{i}\" source=\"p{i}\" target=\"t\"/>");
    }
    net += "</page></net></pnml>";
    std::fs::write(&wide, net).unwrap();
    let analysis = ok_json(&["petri", "analyze", s(&wide), "--json"]);
    assert_eq!(analysis["places"], places);
    assert_eq!(analysis["states"], 2);
    let resident_mb = analysis["peak_resident_bytes"].as_f64().unwrap() / 1e6;
    println!("10,000 places: {resident_mb:.0} MB resident at most");
    assert!(resident_mb < 200.0, "{resident_mb:.0} MB");
    let invariants = ok_json(&["petri", "invariants", s(&wide), "--json"]);
    assert_eq!(invariants["conservative"], false, "{invariants}");
}
