//! `vl petri analyze`: boundedness, safeness, deadlocks, liveness,
//! reversibility and the flow bases, as vl-petri's verdict finds them.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;
use vl_petri::verdict;

use crate::alloc::{peak_bytes, peak_resident_bytes};
use crate::report::{Report, Table, count, emit, yes};

use super::io::{cost_rows, load, place_ids, with_progress};

/// `vl petri analyze`: the keys a program reads. Properties that need the
/// full reachability graph are null for an unbounded net.
#[derive(Serialize)]
struct AnalyzeReport {
    net: String,
    places: usize,
    transitions: usize,
    states: Option<usize>,
    edges: Option<usize>,
    bounded: bool,
    /// The places that can grow without limit (Karp–Miller's ω).
    unbounded_places: Vec<String>,
    max_tokens_in_place: Option<u32>,
    max_tokens_per_marking: Option<u64>,
    safe: bool,
    deadlock: Option<bool>,
    deadlock_trace: Option<Vec<String>>,
    quasi_live: Option<bool>,
    live: Option<bool>,
    /// Transitions below L4, with their level.
    not_live: Vec<String>,
    reversible: Option<bool>,
    /// Null when the net has too many minimal P-invariants to decide it this way.
    conservative: Option<bool>,
    p_flow_basis_dim: usize,
    t_flow_basis_dim: usize,
    seconds: f64,
    /// The most heap bytes live at once.
    peak_heap_bytes: usize,
    /// The process's peak resident memory.
    peak_resident_bytes: usize,
    #[serde(skip)]
    bytes_per_marking: usize,
}

pub(super) fn analyze_command(path: &Path, json: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    let rank = vl_petri::incidence_rank(&net);
    let mut report = AnalyzeReport {
        net: net.id.clone(),
        places: net.places.len(),
        transitions: net.transitions.len(),
        states: None,
        edges: None,
        bounded: false,
        unbounded_places: Vec::new(),
        max_tokens_in_place: None,
        max_tokens_per_marking: None,
        safe: false,
        deadlock: None,
        deadlock_trace: None,
        quasi_live: None,
        live: None,
        not_live: Vec::new(),
        reversible: None,
        conservative: None,
        p_flow_basis_dim: net.places.len() - rank,
        t_flow_basis_dim: net.transitions.len() - rank,
        seconds: 0.0,
        peak_heap_bytes: 0,
        peak_resident_bytes: 0,
        bytes_per_marking: 0,
    };
    let found = with_progress(path, max_states, |options| verdict(&net, options))?;
    report.conservative = found.conservative;
    report.unbounded_places = place_ids(&net, &found.unbounded);
    if let Some(a) = found.analysis {
        report.states = Some(a.states);
        report.edges = Some(a.edges);
        report.bounded = a.bounded;
        report.max_tokens_in_place = Some(a.max_tokens_in_place);
        report.max_tokens_per_marking = Some(a.max_tokens_per_marking);
        report.safe = a.safe;
        report.deadlock = Some(a.deadlock);
        report.deadlock_trace = a.deadlock_trace;
        report.quasi_live = Some(a.quasi_live);
        report.live = Some(a.live);
        report.reversible = Some(a.reversible);
        report.not_live = a
            .liveness
            .iter()
            .zip(&net.transitions)
            .filter(|(l, _)| **l != vl_petri::Liveness::L4)
            .map(|(l, t)| format!("{} {l:?}", t.id))
            .collect();
        report.bytes_per_marking = a.bytes_per_marking;
    }
    report.seconds = started.elapsed().as_secs_f64();
    report.peak_heap_bytes = peak_bytes();
    report.peak_resident_bytes = peak_resident_bytes();
    emit(&report, json)?;
    Ok(ExitCode::SUCCESS)
}

impl Report for AnalyzeReport {
    fn table(&self) -> Table {
        let net = format!(
            "{} ({}, {})",
            self.net,
            count(self.places as u64, "place", "places"),
            count(self.transitions as u64, "transition", "transitions")
        );
        let (Some(states), Some(edges)) = (self.states, self.edges) else {
            return Table::pairs([
                ("net", net),
                (
                    "bounded",
                    format!(
                        "no: {} can grow without limit",
                        self.unbounded_places.join(", ")
                    ),
                ),
            ])
            .note("see `vl petri coverability` for the ω-markings");
        };
        let maybe = |b: Option<bool>| b.map_or("–", yes).to_owned();
        let trace = match &self.deadlock_trace {
            Some(t) if t.is_empty() => "the initial marking is dead".to_owned(),
            Some(t) => t.join(" "),
            None => "–".to_owned(),
        };
        let not_live = match self.not_live.len() {
            0 => "–".to_owned(),
            n if n > 12 => format!("{} … and {} more", self.not_live[..12].join(", "), n - 12),
            _ => self.not_live.join(", "),
        };
        Table::pairs(
            [
                ("net", net),
                ("states", states.to_string()),
                ("edges", edges.to_string()),
                (
                    "bounded",
                    format!(
                        "{} (at most {} in a place, {} in a marking)",
                        yes(self.bounded),
                        count(self.max_tokens_in_place.unwrap_or(0), "token", "tokens"),
                        count(self.max_tokens_per_marking.unwrap_or(0), "token", "tokens"),
                    ),
                ),
                ("safe", yes(self.safe).to_owned()),
                ("deadlock", maybe(self.deadlock)),
                ("  reached by", trace),
                ("quasi-live", maybe(self.quasi_live)),
                ("live", maybe(self.live)),
                ("  not L4", not_live),
                ("reversible", maybe(self.reversible)),
                ("conservative", maybe(self.conservative)),
                (
                    "P-flow basis",
                    format!("dimension {}", self.p_flow_basis_dim),
                ),
                (
                    "T-flow basis",
                    format!("dimension {}", self.t_flow_basis_dim),
                ),
            ]
            .into_iter()
            .chain(cost_rows(
                states,
                self.seconds,
                self.peak_heap_bytes,
                self.peak_resident_bytes,
                self.bytes_per_marking,
            )),
        )
    }
}
