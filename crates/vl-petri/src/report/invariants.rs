//! `vl petri invariants`: the minimal P- and T-invariants as weighted sums
//! of the net's places and transitions, and what they conserve.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::{Invariant, Net, incidence_rank, is_conservative};
use vl_report::table::{Report, Table, count, yes};

/// The invariants in the net's names.
#[derive(Debug, Serialize)]
pub struct InvariantsReport {
    /// Each one: place id → weight.
    pub p_invariants: Vec<BTreeMap<String, u64>>,
    /// Each one: transition id → weight.
    pub t_invariants: Vec<BTreeMap<String, u64>>,
    pub p_flow_basis_dim: usize,
    pub t_flow_basis_dim: usize,
    pub conservative: bool,
    /// Each P-invariant's weighted sum in the initial marking: what it keeps.
    #[serde(skip)]
    pub p_sums: Vec<u64>,
}

impl InvariantsReport {
    pub fn of(net: &Net, p: &[Invariant], t: &[Invariant]) -> InvariantsReport {
        let rank = incidence_rank(net);
        let place_ids: Vec<&str> = net.places.iter().map(|p| p.id.as_str()).collect();
        let transition_ids: Vec<&str> = net.transitions.iter().map(|t| t.id.as_str()).collect();
        let named = |inv: &Invariant, ids: &[&str]| {
            inv.iter().map(|&(i, k)| (ids[i].to_owned(), k)).collect()
        };
        InvariantsReport {
            p_invariants: p.iter().map(|i| named(i, &place_ids)).collect(),
            t_invariants: t.iter().map(|i| named(i, &transition_ids)).collect(),
            p_flow_basis_dim: net.places.len() - rank,
            t_flow_basis_dim: net.transitions.len() - rank,
            conservative: is_conservative(net.places.len(), p),
            p_sums: p
                .iter()
                .map(|inv| {
                    inv.iter()
                        .map(|&(i, k)| k * u64::from(net.places[i].initial))
                        .sum()
                })
                .collect(),
        }
    }
}

/// An invariant as people write it: `p1 + 2·p2`.
fn sum(inv: &BTreeMap<String, u64>) -> String {
    inv.iter()
        .map(|(id, k)| match k {
            1 => id.clone(),
            _ => format!("{k}·{id}"),
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

impl Report for InvariantsReport {
    fn table(&self) -> Table {
        let mut table = Table::default().title(format!(
            "{} (P-flow basis dimension {}):",
            count(
                self.p_invariants.len() as u64,
                "minimal P-invariant",
                "minimal P-invariants"
            ),
            self.p_flow_basis_dim
        ));
        for (inv, m0) in self.p_invariants.iter().zip(&self.p_sums) {
            table = table.title(format!("  {} = {m0}", sum(inv)));
        }
        table = table.title(format!(
            "{} (T-flow basis dimension {}):",
            count(
                self.t_invariants.len() as u64,
                "minimal T-invariant",
                "minimal T-invariants"
            ),
            self.t_flow_basis_dim
        ));
        for inv in &self.t_invariants {
            table = table.title(format!("  {}", sum(inv)));
        }
        table.title(format!("conservative: {}", yes(self.conservative)))
    }
}
