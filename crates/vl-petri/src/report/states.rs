//! `vl petri states`: how many markings, how many firings, the bounds.

use std::collections::BTreeMap;

use serde::Serialize;

use super::{Cost, net_line};
use crate::{Net, StateCount};
use vl_report::table::{Report, Table, count};

/// The state space counted: its size and each place's bound.
#[derive(Debug, Serialize)]
pub struct StatesReport {
    pub net: String,
    pub places: usize,
    pub transitions: usize,
    pub states: usize,
    pub edges: usize,
    pub max_tokens_in_place: u32,
    pub max_tokens_per_marking: u64,
    pub place_bounds: BTreeMap<String, u32>,
    #[serde(flatten)]
    pub cost: Cost,
    pub bytes_per_marking: usize,
}

impl StatesReport {
    /// `found` in `net`'s names, at the `cost` it took.
    pub fn of(net: &Net, found: &StateCount, cost: Cost) -> StatesReport {
        StatesReport {
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
            cost,
            bytes_per_marking: found.bytes_per_marking,
        }
    }
}

impl Report for StatesReport {
    fn table(&self) -> Table {
        Table::pairs(
            [
                ("net", net_line(&self.net, self.places, self.transitions)),
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
            .chain(self.cost.rows(self.states, self.bytes_per_marking)),
        )
        .note("each place's bound: --json")
    }
}
