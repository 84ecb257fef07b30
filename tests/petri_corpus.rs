//! `vl petri analyze --json` and `vl petri states --json` against the Model Checking Contest's certified
//! answers for every small and medium model in assets/petri-corpus.

use std::path::Path;
use std::process::Command;

use serde_json::Value;
use vl_petri::{CorpusModel, Manifest};

fn corpus() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/petri-corpus"))
}

fn manifest() -> Manifest {
    let text = std::fs::read_to_string(corpus().join("manifest.csv"))
        .expect("the corpus manifest is in the repo");
    Manifest::parse(&text).expect("the manifest parses")
}

/// `vl petri COMMAND --json ARGS…` on every small and medium model, with its report.
fn reports(
    command: &'static str,
    args: &'static [&'static str],
) -> impl Iterator<Item = (CorpusModel, Value)> {
    manifest()
        .models
        .into_iter()
        .filter(|model| model.tier() != "large")
        .map(move |model| {
            let out = Command::new(env!("CARGO_BIN_EXE_vl"))
                .args(["petri", command, "--json"])
                .args(args)
                .arg(corpus().join(model.pnml()))
                .output()
                .expect("vl runs");
            assert!(
                out.status.success(),
                "{}: {}",
                model.name(),
                String::from_utf8_lossy(&out.stderr)
            );
            let got = serde_json::from_slice(&out.stdout).expect("JSON report");
            (model, got)
        })
}

#[test]
fn analysis_matches_the_certified_answers() {
    let mut checked = 0;
    let mut decided_conservative = 0;
    let mut mismatches = Vec::new();
    for (model, got) in reports("analyze", &[]) {
        let number = |key: &str| got[key].as_u64().map(|v| v.to_string()).unwrap_or_default();
        let verdict = |key: &str| {
            got[key]
                .as_bool()
                .map(|b| b.to_string().to_uppercase())
                .unwrap_or_default()
        };
        let checks = [
            ("states", "states", number("states")),
            ("rg_edges", "edges", number("edges")),
            (
                "max_tokens_in_place",
                "max_tokens_in_place",
                number("max_tokens_in_place"),
            ),
            (
                "max_tokens_per_marking",
                "max_tokens_per_marking",
                number("max_tokens_per_marking"),
            ),
            ("deadlock", "deadlock", verdict("deadlock")),
            ("one_safe", "safe", verdict("safe")),
            ("quasi_live", "quasi_live", verdict("quasi_live")),
            ("live", "live", verdict("live")),
            (
                "p_flow_basis_dim",
                "p_flow_basis_dim",
                number("p_flow_basis_dim"),
            ),
            (
                "t_flow_basis_dim",
                "t_flow_basis_dim",
                number("t_flow_basis_dim"),
            ),
        ];
        for (column, key, value) in checks {
            let expected = model.get(column).unwrap_or_default();
            if !expected.is_empty() && expected != value {
                mismatches.push(format!(
                    "{}: {key} = {value}, certified {expected}",
                    model.name()
                ));
            }
        }
        // Not certified, but the LP check in the manifest must agree when we decide it.
        if let Some(c) = got["conservative"].as_bool() {
            let expected = model
                .get("conservative_weighted_derived")
                .unwrap_or_default()
                .to_lowercase();
            if expected != c.to_string() {
                mismatches.push(format!(
                    "{}: conservative = {c}, LP check says {expected}",
                    model.name()
                ));
            }
            decided_conservative += 1;
        }
        if got["deadlock"] == true {
            assert!(
                got["deadlock_trace"].is_array(),
                "{}: a deadlock comes with its trace",
                model.name()
            );
        }
        checked += 1;
    }
    assert!(
        mismatches.is_empty(),
        "{} mismatches:\n{}",
        mismatches.len(),
        mismatches.join("\n")
    );
    assert!(checked >= 60, "only {checked} models checked");
    assert!(
        decided_conservative >= 30,
        "conservativeness decided for only {decided_conservative} models"
    );
}

/// `vl petri states --json` counts what verifypn -e does on every small and
/// medium model: its states, its firings ("discovered states" less one) and
/// the certified bounds, without keeping the graph; on two threads, as on one.
#[test]
fn states_match_verifypn_s_counts() {
    let mut checked = 0;
    let mut mismatches = Vec::new();
    let one = reports("states", &[]);
    let two = reports("states", &["--threads", "2"]);
    for ((model, got), (_, got_on_two)) in one.zip(two) {
        assert_eq!(got_on_two["states"], got["states"], "{}", model.name());
        assert_eq!(got_on_two["edges"], got["edges"], "{}", model.name());
        assert_eq!(
            got_on_two["place_bounds"],
            got["place_bounds"],
            "{}",
            model.name()
        );
        let number = |key: &str| got[key].as_u64().map(|v| v.to_string()).unwrap_or_default();
        let bounds = got["place_bounds"].as_object().expect("bounds by place");
        assert_eq!(bounds.len(), got["places"].as_u64().unwrap() as usize);
        let highest = bounds.values().filter_map(Value::as_u64).max();
        assert_eq!(
            highest.map(|b| b.to_string()).unwrap_or_default(),
            number("max_tokens_in_place"),
            "{}",
            model.name()
        );
        for (column, key) in [
            ("verifypn_states", "states"),
            ("rg_edges", "edges"),
            ("max_tokens_in_place", "max_tokens_in_place"),
            ("max_tokens_per_marking", "max_tokens_per_marking"),
        ] {
            let expected = model.get(column).unwrap_or_default();
            if !expected.is_empty() && expected != number(key) {
                mismatches.push(format!(
                    "{}: {key} = {}, {column} {expected}",
                    model.name(),
                    number(key)
                ));
            }
        }
        checked += 1;
    }
    assert!(checked >= 60, "only {checked} models");
    assert!(mismatches.is_empty(), "{}", mismatches.join("\n"));
}
