//! `vl petri analyze`: boundedness, safeness, deadlocks, liveness,
//! reversibility and the flow bases, as [`verdict`](crate::verdict) found them.

use serde::Serialize;

use super::{Cost, net_line, place_ids};
use crate::{Liveness, Net, NetVerdict};
use vl_report::table::{Report, Table, count, yes};

/// Transitions named in the table before "… and N more".
const NOT_LIVE_SHOWN: usize = 12;

/// The keys a program reads. Properties that need the full reachability
/// graph are null for an unbounded net.
#[derive(Debug, Serialize)]
pub struct AnalysisReport {
    pub net: String,
    pub places: usize,
    pub transitions: usize,
    pub states: Option<usize>,
    pub edges: Option<usize>,
    pub bounded: bool,
    /// The places that can grow without limit (Karp–Miller's ω).
    pub unbounded_places: Vec<String>,
    pub max_tokens_in_place: Option<u32>,
    pub max_tokens_per_marking: Option<u64>,
    pub safe: bool,
    pub deadlock: Option<bool>,
    pub deadlock_trace: Option<Vec<String>>,
    pub quasi_live: Option<bool>,
    pub live: Option<bool>,
    /// Transitions below L4, with their level.
    pub not_live: Vec<String>,
    pub reversible: Option<bool>,
    /// Null when the net has too many minimal P-invariants to decide it this way.
    pub conservative: Option<bool>,
    pub p_flow_basis_dim: usize,
    pub t_flow_basis_dim: usize,
    #[serde(flatten)]
    pub cost: Cost,
    #[serde(skip)]
    pub bytes_per_marking: usize,
}

impl AnalysisReport {
    /// `found` in `net`'s names, at the `cost` it took.
    pub fn of(net: &Net, found: NetVerdict, cost: Cost) -> AnalysisReport {
        let rank = crate::incidence_rank(net);
        let a = found.analysis;
        AnalysisReport {
            net: net.id.clone(),
            places: net.places.len(),
            transitions: net.transitions.len(),
            states: a.as_ref().map(|a| a.states),
            edges: a.as_ref().map(|a| a.edges),
            bounded: a.as_ref().is_some_and(|a| a.bounded),
            unbounded_places: place_ids(net, &found.unbounded),
            max_tokens_in_place: a.as_ref().map(|a| a.max_tokens_in_place),
            max_tokens_per_marking: a.as_ref().map(|a| a.max_tokens_per_marking),
            safe: a.as_ref().is_some_and(|a| a.safe),
            deadlock: a.as_ref().map(|a| a.deadlock),
            quasi_live: a.as_ref().map(|a| a.quasi_live),
            live: a.as_ref().map(|a| a.live),
            not_live: a.as_ref().map_or_else(Vec::new, |a| {
                a.liveness
                    .iter()
                    .zip(&net.transitions)
                    .filter(|(l, _)| **l != Liveness::L4)
                    .map(|(l, t)| format!("{} {l:?}", t.id))
                    .collect()
            }),
            reversible: a.as_ref().map(|a| a.reversible),
            conservative: found.conservative,
            p_flow_basis_dim: net.places.len() - rank,
            t_flow_basis_dim: net.transitions.len() - rank,
            cost,
            bytes_per_marking: a.as_ref().map_or(0, |a| a.bytes_per_marking),
            deadlock_trace: a.and_then(|a| a.deadlock_trace),
        }
    }

    /// The table of a net whose graph was not explored: it is unbounded.
    fn unbounded_table(&self, net: String) -> Table {
        Table::pairs([
            ("net", net),
            (
                "bounded",
                format!(
                    "no: {} can grow without limit",
                    self.unbounded_places.join(", ")
                ),
            ),
        ])
        .note("see `vl petri coverability` for the ω-markings")
    }
}

impl Report for AnalysisReport {
    fn table(&self) -> Table {
        let net = net_line(&self.net, self.places, self.transitions);
        let (Some(states), Some(edges)) = (self.states, self.edges) else {
            return self.unbounded_table(net);
        };
        let maybe = |b: Option<bool>| b.map_or("–", yes).to_owned();
        let trace = match &self.deadlock_trace {
            Some(t) if t.is_empty() => "the initial marking is dead".to_owned(),
            Some(t) => t.join(" "),
            None => "–".to_owned(),
        };
        let not_live = match self.not_live.len() {
            0 => "–".to_owned(),
            n if n > NOT_LIVE_SHOWN => format!(
                "{} … and {} more",
                self.not_live[..NOT_LIVE_SHOWN].join(", "),
                n - NOT_LIVE_SHOWN
            ),
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
            .chain(self.cost.rows(states, self.bytes_per_marking)),
        )
    }
}
