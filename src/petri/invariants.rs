//! `vl petri invariants`: the minimal P- and T-invariants.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use serde::Serialize;
use vl_petri::{Invariant, Net, TooManyInvariants, is_conservative, p_invariants, t_invariants};

use crate::report::{Report, Table, count, emit, yes};

use super::io::load;

/// `vl petri invariants`: each invariant as element id → weight.
#[derive(Serialize)]
struct InvariantsReport {
    p_invariants: Vec<serde_json::Map<String, serde_json::Value>>,
    t_invariants: Vec<serde_json::Map<String, serde_json::Value>>,
    p_flow_basis_dim: usize,
    t_flow_basis_dim: usize,
    conservative: bool,
    /// Each P-invariant's weighted token sum, the same in every reachable marking.
    #[serde(skip)]
    p_sums: Vec<u64>,
}

impl InvariantsReport {
    fn new(net: &Net, p: &[Invariant], t: &[Invariant]) -> InvariantsReport {
        let rank = vl_petri::incidence_rank(net);
        let place_ids: Vec<&str> = net.places.iter().map(|p| p.id.as_str()).collect();
        let transition_ids: Vec<&str> = net.transitions.iter().map(|t| t.id.as_str()).collect();
        let as_map = |inv: &Invariant, ids: &[&str]| {
            inv.iter()
                .map(|&(i, k)| (ids[i].to_owned(), serde_json::json!(k)))
                .collect()
        };
        InvariantsReport {
            p_invariants: p.iter().map(|i| as_map(i, &place_ids)).collect(),
            t_invariants: t.iter().map(|i| as_map(i, &transition_ids)).collect(),
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

impl Report for InvariantsReport {
    fn table(&self) -> Table {
        let sum = |inv: &serde_json::Map<String, serde_json::Value>| -> String {
            inv.iter()
                .map(|(id, k)| match k.as_u64() {
                    Some(1) => id.clone(),
                    _ => format!("{k}·{id}"),
                })
                .collect::<Vec<_>>()
                .join(" + ")
        };
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

pub(super) fn invariants_command(path: &Path, json: bool, max_rows: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let describe = |e: TooManyInvariants| {
        anyhow::anyhow!("{}: {e}; raise --max-rows to go on", path.display())
    };
    let p = p_invariants(&net, max_rows).map_err(describe)?;
    let t = t_invariants(&net, max_rows).map_err(describe)?;
    emit(&InvariantsReport::new(&net, &p, &t), json)?;
    Ok(ExitCode::SUCCESS)
}
