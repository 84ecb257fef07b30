//! What the petri subcommands share: reading and writing nets, a search
//! with its progress shown, and what it cost.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use vl_petri::{Cost, ExploreError, Net, Options, Progress, from_pnml};

use crate::BadInput;
use crate::shipped::read_input;
use vl_report::{peak_bytes, peak_resident_bytes};

/// Reads a PNML file (or a shipped example net); any problem with it is
/// the user's input, exit code 2.
pub(super) fn load(path: &Path) -> Result<Net> {
    let text = read_input(path)?;
    Ok(from_pnml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?)
}

pub(super) fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
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
        deadline: None,
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

/// What a search begun at `started` cost this process.
pub(super) fn cost_since(started: Instant) -> Cost {
    Cost {
        seconds: started.elapsed().as_secs_f64(),
        peak_heap_bytes: peak_bytes(),
        peak_resident_bytes: peak_resident_bytes(),
    }
}
