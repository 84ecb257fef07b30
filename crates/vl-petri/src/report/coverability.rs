//! `vl petri coverability`: whether the net is bounded, which places grow,
//! and the maximal ω-markings of its Karp–Miller graph.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Serialize, Serializer};

use super::place_ids;
use crate::{Coverability, Net, OMEGA};
use vl_report::table::{Report, Table, yes};

/// Tokens in a place of an ω-marking: a count, or ω (as many as wanted).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tokens(pub u32);

impl fmt::Display for Tokens {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            OMEGA => f.write_str("ω"),
            n => write!(f, "{n}"),
        }
    }
}

/// A count as a JSON number, ω as the string "ω".
impl Serialize for Tokens {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.0 {
            OMEGA => s.serialize_str("ω"),
            n => s.serialize_u32(n),
        }
    }
}

/// The Karp–Miller graph in the net's names.
#[derive(Debug, Serialize)]
pub struct CoverabilityReport {
    pub bounded: bool,
    pub unbounded_places: Vec<String>,
    /// Place id → tokens, empty places left out.
    pub maximal: Vec<BTreeMap<String, Tokens>>,
    pub nodes: usize,
}

impl CoverabilityReport {
    pub fn of(net: &Net, c: &Coverability) -> CoverabilityReport {
        CoverabilityReport {
            bounded: c.bounded(),
            unbounded_places: place_ids(net, &c.unbounded),
            maximal: c
                .maximal()
                .into_iter()
                .map(|m| {
                    m.iter()
                        .zip(&net.places)
                        .filter(|(v, _)| **v > 0)
                        .map(|(&v, p)| (p.id.clone(), Tokens(v)))
                        .collect()
                })
                .collect(),
            nodes: c.nodes.len(),
        }
    }
}

impl Report for CoverabilityReport {
    fn table(&self) -> Table {
        let unbounded = if self.unbounded_places.is_empty() {
            "–".to_owned()
        } else {
            self.unbounded_places.join(", ")
        };
        let mut table = Table::pairs([
            ("bounded", yes(self.bounded).to_owned()),
            ("unbounded places", unbounded),
            ("graph nodes", self.nodes.to_string()),
        ])
        .note("maximal markings:");
        for m in &self.maximal {
            let cells: Vec<String> = m.iter().map(|(p, v)| format!("{p}={v}")).collect();
            table = table.note(format!("  {{{}}}", cells.join(", ")));
        }
        table
    }
}
