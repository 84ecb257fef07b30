//! What an analysis found, in the net's own names (place and transition
//! ids), for people as a [`Table`] and for programs as JSON: one report per
//! question `vl petri` answers. The cost rows (time, memory) are measured
//! by whoever ran the search and filled in as a [`Cost`].

mod analysis;
mod coverability;
mod invariants;
mod states;

use serde::Serialize;

use crate::Net;
use vl_report::table::count;

pub use analysis::AnalysisReport;
pub use coverability::{CoverabilityReport, Tokens};
pub use invariants::InvariantsReport;
pub use states::StatesReport;

/// What a search cost: its time and the memory it held.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Cost {
    pub seconds: f64,
    /// The most heap bytes live at once.
    pub peak_heap_bytes: usize,
    /// The process's peak resident memory.
    pub peak_resident_bytes: usize,
}

impl Cost {
    /// The time and memory rows, for `states` markings of `bytes_per_marking`.
    fn rows(&self, states: usize, bytes_per_marking: usize) -> [(&'static str, String); 2] {
        [
            (
                "time",
                format!(
                    "{:.3} s, {} states/s",
                    self.seconds,
                    (states as f64 / self.seconds.max(1e-9)) as u64
                ),
            ),
            (
                "memory",
                format!(
                    "{:.1} MB heap peak, {:.1} MB resident peak, {} per marking",
                    self.peak_heap_bytes as f64 / 1e6,
                    self.peak_resident_bytes as f64 / 1e6,
                    count(bytes_per_marking as u64, "byte", "bytes")
                ),
            ),
        ]
    }
}

/// The net's name with its size, as a report's first row.
fn net_line(net: &str, places: usize, transitions: usize) -> String {
    format!(
        "{net} ({}, {})",
        count(places as u64, "place", "places"),
        count(transitions as u64, "transition", "transitions")
    )
}

/// The ids of `places`.
fn place_ids(net: &Net, places: &[usize]) -> Vec<String> {
    places.iter().map(|&p| net.places[p].id.clone()).collect()
}
