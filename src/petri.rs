//! `vl petri …`: the thesis's methodology as commands — analyse nets (and
//! later compose them and synthesise their controllers).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use clap::Subcommand;
use serde::Serialize;
use vl_petri::{ExploreError, Net, Options, Progress, analyze, explore, from_pnml};

use crate::BadInput;
use crate::alloc::peak_bytes;

#[derive(Subcommand)]
pub enum PetriCommand {
    /// Explore the reachability graph and report boundedness, safeness,
    /// deadlocks, liveness, reversibility and the flow-basis dimensions.
    Analyze {
        /// The net, as PNML.
        net: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Stop exploring after this many states.
        #[arg(long, default_value_t = 100_000_000)]
        max_states: usize,
    },
}

pub fn run(command: PetriCommand) -> Result<ExitCode> {
    match command {
        PetriCommand::Analyze {
            net,
            json,
            max_states,
        } => analyze_command(&net, json, max_states),
    }
}

/// Reads a PNML file; any problem with it is the user's input, exit code 2.
fn load(path: &Path) -> Result<Net> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| BadInput(format!("cannot read {}: {e}", path.display())))?;
    Ok(from_pnml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?)
}

/// `vl petri analyze --json`: the keys a program reads.
#[derive(Serialize)]
struct AnalyzeReport {
    places: usize,
    transitions: usize,
    states: Option<usize>,
    edges: Option<usize>,
    bounded: bool,
    max_tokens_in_place: u32,
    max_tokens_per_marking: u64,
    safe: bool,
    deadlock: bool,
    deadlock_trace: Option<Vec<String>>,
    quasi_live: bool,
    live: bool,
    reversible: bool,
    p_flow_basis_dim: usize,
    t_flow_basis_dim: usize,
    seconds: f64,
    peak_bytes: usize,
}

fn analyze_command(path: &Path, json: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
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
    let space = match explore(&net, options) {
        Ok(space) => space,
        Err(e @ ExploreError::TooManyStates { .. }) => {
            if show_progress {
                eprintln!();
            }
            anyhow::bail!("{}: {e}; raise --max-states to go on", path.display());
        }
        Err(e) => anyhow::bail!("{}: {e}", path.display()),
    };
    if show_progress {
        eprint!("\r{:78}\r", "");
    }
    let a = analyze(&net, &space);
    let report = AnalyzeReport {
        places: a.places,
        transitions: a.transitions,
        states: Some(a.states),
        edges: Some(a.edges),
        bounded: a.bounded,
        max_tokens_in_place: a.max_tokens_in_place,
        max_tokens_per_marking: a.max_tokens_per_marking,
        safe: a.safe,
        deadlock: a.deadlock,
        deadlock_trace: a.deadlock_trace.clone(),
        quasi_live: a.quasi_live,
        live: a.live,
        reversible: a.reversible,
        p_flow_basis_dim: a.p_flow_basis_dim,
        t_flow_basis_dim: a.t_flow_basis_dim,
        seconds: started.elapsed().as_secs_f64(),
        peak_bytes: peak_bytes(),
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let yes = |b: bool| if b { "yes" } else { "no" };
    let trace = match &a.deadlock_trace {
        Some(t) if t.is_empty() => "the initial marking is dead".to_owned(),
        Some(t) => t.join(" "),
        None => "–".to_owned(),
    };
    let rows = [
        (
            "net",
            format!(
                "{} ({} places, {} transitions)",
                net.id, a.places, a.transitions
            ),
        ),
        ("states", a.states.to_string()),
        ("edges", a.edges.to_string()),
        (
            "bounded",
            format!(
                "{} (at most {} tokens in a place, {} in a marking)",
                yes(a.bounded),
                a.max_tokens_in_place,
                a.max_tokens_per_marking
            ),
        ),
        ("safe", yes(a.safe).to_owned()),
        ("deadlock", yes(a.deadlock).to_owned()),
        ("  reached by", trace),
        ("quasi-live", yes(a.quasi_live).to_owned()),
        ("live", yes(a.live).to_owned()),
        ("reversible", yes(a.reversible).to_owned()),
        ("P-flow basis", format!("dimension {}", a.p_flow_basis_dim)),
        ("T-flow basis", format!("dimension {}", a.t_flow_basis_dim)),
        (
            "time",
            format!(
                "{:.3} s, {} states/s",
                report.seconds,
                (a.states as f64 / report.seconds.max(1e-9)) as u64
            ),
        ),
        (
            "memory",
            format!(
                "{:.1} MB peak, {} bytes per marking",
                report.peak_bytes as f64 / 1e6,
                space.bytes_per_marking()
            ),
        ),
    ];
    for (name, value) in rows {
        println!("{name:<14} {value}");
    }
    Ok(ExitCode::SUCCESS)
}
