//! `vl petri coverability`: the Karp–Miller tree, for nets that may be
//! unbounded.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use serde::Serialize;
use vl_petri::{Coverability, CoverabilityError, Net, coverability, graph_to_dot};

use crate::BadInput;
use crate::report::{Report, Table, emit, yes};

use super::io::{load, omega_marking, place_ids, write_file};

/// `vl petri coverability`.
#[derive(Serialize)]
struct CoverabilityReport {
    bounded: bool,
    unbounded_places: Vec<String>,
    maximal: Vec<serde_json::Map<String, serde_json::Value>>,
    nodes: usize,
}

impl CoverabilityReport {
    fn new(net: &Net, c: &Coverability) -> CoverabilityReport {
        CoverabilityReport {
            bounded: c.bounded(),
            unbounded_places: place_ids(net, &c.unbounded),
            maximal: c
                .maximal()
                .into_iter()
                .map(|m| omega_marking(net, m))
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
            let cells: Vec<String> = m
                .iter()
                .map(|(p, v)| {
                    let v = v.as_str().map_or_else(|| v.to_string(), str::to_owned);
                    format!("{p}={v}")
                })
                .collect();
            table = table.note(format!("  {{{}}}", cells.join(", ")));
        }
        table
    }
}

pub(super) fn coverability_command(
    path: &Path,
    json: bool,
    dot: Option<&Path>,
    max_nodes: usize,
) -> Result<ExitCode> {
    let net = load(path)?;
    let c = coverability(&net, max_nodes).map_err(|e| match e {
        CoverabilityError::TooLarge(_) => anyhow::anyhow!("{}: {e}", path.display()),
        refused => BadInput(format!("{}: {refused}", path.display())).into(),
    })?;
    if let Some(file) = dot {
        let picture = graph_to_dot(
            &net,
            &format!("coverability of {}", net.id),
            &c.nodes,
            &c.edges,
        );
        write_file(file, &picture)?;
    }
    emit(&CoverabilityReport::new(&net, &c), json)?;
    Ok(ExitCode::SUCCESS)
}
