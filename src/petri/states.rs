//! `vl petri states`: what exploration alone finds, as `verifypn -e`
//! reports it.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;
use vl_petri::count_states;

use crate::alloc::{peak_bytes, peak_resident_bytes};
use crate::report::{Report, Table, count, emit};

use super::io::{cost_rows, load, with_progress};

/// `vl petri states`: what exploration alone finds, as `verifypn -e` reports it.
#[derive(Serialize)]
struct StatesReport {
    net: String,
    places: usize,
    transitions: usize,
    states: usize,
    /// Firings between markings (verifypn's "discovered states" less one).
    edges: usize,
    max_tokens_in_place: u32,
    max_tokens_per_marking: u64,
    /// Each place's bound, by place id.
    place_bounds: std::collections::BTreeMap<String, u32>,
    seconds: f64,
    peak_heap_bytes: usize,
    peak_resident_bytes: usize,
    bytes_per_marking: usize,
}

pub(super) fn states_command(
    path: &Path,
    json: bool,
    max_states: usize,
    threads: usize,
) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    let found = with_progress(path, max_states, |options| {
        count_states(&net, options, threads)
    })?;
    let report = StatesReport {
        net: net.id.clone(),
        places: net.places.len(),
        transitions: net.transitions.len(),
        states: found.states,
        edges: found.edges,
        max_tokens_in_place: found.bounds.per_place(),
        max_tokens_per_marking: found.bounds.per_marking,
        place_bounds: net
            .places
            .iter()
            .zip(&found.bounds.places)
            .map(|(p, &b)| (p.id.clone(), b))
            .collect(),
        seconds: started.elapsed().as_secs_f64(),
        peak_heap_bytes: peak_bytes(),
        peak_resident_bytes: peak_resident_bytes(),
        bytes_per_marking: found.bytes_per_marking,
    };
    emit(&report, json)?;
    Ok(ExitCode::SUCCESS)
}

impl Report for StatesReport {
    fn table(&self) -> Table {
        Table::pairs(
            [
                (
                    "net",
                    format!(
                        "{} ({}, {})",
                        self.net,
                        count(self.places as u64, "place", "places"),
                        count(self.transitions as u64, "transition", "transitions")
                    ),
                ),
                ("states", self.states.to_string()),
                ("edges", self.edges.to_string()),
                (
                    "bounds",
                    format!(
                        "at most {} in a place, {} in a marking",
                        count(self.max_tokens_in_place, "token", "tokens"),
                        count(self.max_tokens_per_marking, "token", "tokens"),
                    ),
                ),
            ]
            .into_iter()
            .chain(cost_rows(
                self.states,
                self.seconds,
                self.peak_heap_bytes,
                self.peak_resident_bytes,
                self.bytes_per_marking,
            )),
        )
        .note("each place's bound: --json")
    }
}
