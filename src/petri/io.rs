//! What the petri subcommands share: reading and writing nets, a search
//! with its progress shown, and how its cost and places are printed.

use std::io::IsTerminal;
use std::path::Path;

use anyhow::Result;
use vl_petri::{ExploreError, Net, OMEGA, Options, Progress, StateSpace, explore, from_pnml};

use crate::BadInput;
use crate::report::count;
use crate::shipped::read_input;

/// Reads a PNML file (or a shipped example net); any problem with it is
/// the user's input, exit code 2.
pub(super) fn load(path: &Path) -> Result<Net> {
    let text = read_input(path)?;
    Ok(from_pnml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?)
}

pub(super) fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

/// Explores the reachability graph, showing progress on a terminal.
pub(super) fn explore_with_progress(
    net: &Net,
    path: &Path,
    max_states: usize,
) -> Result<StateSpace> {
    with_progress(path, max_states, |options| explore(net, options))
}

/// Runs a search (`explore` or `count_states`) with `--max-states`, its
/// progress on a terminal, and its stops said in the user's terms.
pub(super) fn with_progress<T>(
    path: &Path,
    max_states: usize,
    search: impl FnOnce(Options) -> Result<T, ExploreError>,
) -> Result<T> {
    let show_progress = std::io::stderr().is_terminal();
    let mut report_progress = |p: Progress| {
        eprint!(
            "\r{:>12} states {:>14} edges {:>10.0} states/s",
            p.states,
            p.edges,
            p.states as f64 / p.elapsed.as_secs_f64().max(1e-9)
        );
    };
    let options = Options {
        max_states,
        progress: show_progress.then_some(&mut report_progress as &mut dyn FnMut(Progress)),
    };
    let result = search(options);
    if show_progress {
        eprint!("\r{:78}\r", "");
    }
    match result {
        Ok(found) => Ok(found),
        Err(e @ ExploreError::TooManyStates { .. }) => {
            anyhow::bail!(
                "{}: {e}; raise --max-states to go on (if the net may be unbounded, `vl petri coverability` names the places that grow)",
                path.display()
            )
        }
        Err(e) => anyhow::bail!("{}: {e}", path.display()),
    }
}

/// The time and memory rows of `analyze` and `states`.
pub(super) fn cost_rows(
    states: usize,
    seconds: f64,
    peak_heap_bytes: usize,
    peak_resident_bytes: usize,
    bytes_per_marking: usize,
) -> [(&'static str, String); 2] {
    [
        (
            "time",
            format!(
                "{seconds:.3} s, {} states/s",
                (states as f64 / seconds.max(1e-9)) as u64
            ),
        ),
        (
            "memory",
            format!(
                "{:.1} MB heap peak, {:.1} MB resident peak, {} per marking",
                peak_heap_bytes as f64 / 1e6,
                peak_resident_bytes as f64 / 1e6,
                count(bytes_per_marking as u64, "byte", "bytes")
            ),
        ),
    ]
}

pub(super) fn place_ids(net: &Net, places: &[usize]) -> Vec<String> {
    places.iter().map(|&p| net.places[p].id.clone()).collect()
}

/// An ω-marking: place id → count or "ω", empty places left out.
pub(super) fn omega_marking(net: &Net, m: &[u32]) -> serde_json::Map<String, serde_json::Value> {
    m.iter()
        .zip(&net.places)
        .filter(|(v, _)| **v > 0)
        .map(|(&v, p)| {
            let value = if v == OMEGA {
                serde_json::json!("ω")
            } else {
                serde_json::json!(v)
            };
            (p.id.clone(), value)
        })
        .collect()
}
