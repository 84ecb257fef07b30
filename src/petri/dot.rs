//! `vl petri dot`: a net, or its reachability graph, for Graphviz.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use vl_petri::{graph_to_dot, net_to_dot};

use super::io::{load, with_progress};

pub(super) fn dot_command(path: &Path, reachability: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    if !reachability {
        print!("{}", net_to_dot(&net));
        return Ok(ExitCode::SUCCESS);
    }
    let space = with_progress(path, max_states, |options| vl_petri::explore(&net, options))?;
    let nodes: Vec<Vec<u32>> = (0..space.states()).map(|s| space.marking(s).0).collect();
    let edges: Vec<(usize, usize, usize)> = (0..space.states())
        .flat_map(|s| space.successors(s).map(move |(t, to)| (s, t, to)))
        .collect();
    print!(
        "{}",
        graph_to_dot(&net, &format!("reachability of {}", net.id), &nodes, &edges)
    );
    Ok(ExitCode::SUCCESS)
}
