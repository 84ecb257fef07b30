//! Graphviz DOT pictures: of a net (places as circles with their tokens,
//! transitions as boxes, inhibitor arcs ending in a circle) and of a state
//! graph (reachability graph or coverability graph, markings as labels).

use std::fmt::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::coverability::OMEGA;
use crate::net::Net;

/// Whether Graphviz's `dot` is installed, to draw DOT files as SVG.
pub fn graphviz_available() -> bool {
    Command::new("dot")
        .arg("-V")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Why a DOT file was not drawn.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("cannot run Graphviz's dot: {0}")]
    Run(std::io::Error),
    #[error("dot failed on {0}")]
    Failed(String),
}

/// Draws the DOT file `dot` as the SVG file `svg` with Graphviz's `dot`.
pub fn render_svg(dot: &Path, svg: &Path) -> Result<(), RenderError> {
    let status = Command::new("dot")
        .arg("-Tsvg")
        .arg(dot)
        .arg("-o")
        .arg(svg)
        .status()
        .map_err(RenderError::Run)?;
    match status.success() {
        true => Ok(()),
        false => Err(RenderError::Failed(dot.display().to_string())),
    }
}

fn quote(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// Arcs beyond which Graphviz is told to settle its layout early.
const LARGE_NET_ARCS: usize = 500;

/// The net drawn with its initial marking.
pub fn net_to_dot(net: &Net) -> String {
    let mut out = format!("digraph {} {{\n  rankdir=LR;\n", quote(&net.id));
    let arcs: usize = (net.transitions.iter())
        .map(|t| t.pre.len() + t.post.len() + t.inhibit.len())
        .sum();
    if arcs > LARGE_NET_ARCS {
        // Graphviz's ranking and crossing minimisation take half a minute
        // on a composed lab's thousand arcs, for a picture no clearer than
        // the one a tenth of that time gives.
        out.push_str("  nslimit=1;\n  mclimit=0.2;\n");
    }
    for p in &net.places {
        let tokens = match p.initial {
            0 => String::new(),
            1 => "●".to_owned(),
            n => n.to_string(),
        };
        let cap = p.capacity.map(|c| format!(" ≤{c}")).unwrap_or_default();
        let _ = writeln!(
            out,
            "  {} [shape=circle, label={}, xlabel={}];",
            quote(&format!("p:{}", p.id)),
            quote(&tokens),
            quote(&format!("{}{cap}", p.name))
        );
    }
    for t in &net.transitions {
        let label = match &t.label {
            Some(l) if *l != t.name => format!("{}\n⟨{l}⟩", t.name),
            _ => t.name.clone(),
        };
        let _ = writeln!(
            out,
            "  {} [shape=box, style=filled, fillcolor=gray90, label={}];",
            quote(&format!("t:{}", t.id)),
            quote(&label)
        );
    }
    for t in &net.transitions {
        let tid = quote(&format!("t:{}", t.id));
        let weight = |w: u32| {
            if w > 1 {
                format!(" [label={w}]")
            } else {
                String::new()
            }
        };
        for a in &t.pre {
            let pid = quote(&format!("p:{}", net.places[a.place.0].id));
            let _ = writeln!(out, "  {pid} -> {tid}{};", weight(a.weight));
        }
        for a in &t.post {
            let pid = quote(&format!("p:{}", net.places[a.place.0].id));
            let _ = writeln!(out, "  {tid} -> {pid}{};", weight(a.weight));
        }
        for a in &t.inhibit {
            let pid = quote(&format!("p:{}", net.places[a.place.0].id));
            let label = if a.weight > 1 {
                format!(", label={}", a.weight)
            } else {
                String::new()
            };
            let _ = writeln!(out, "  {pid} -> {tid} [arrowhead=odot{label}];");
        }
    }
    out.push_str("}\n");
    out
}

/// A state graph: `nodes` are markings (ω allowed), `edges` are
/// (from, transition, to); the first node is the initial one.
pub fn graph_to_dot(
    net: &Net,
    title: &str,
    nodes: &[Vec<u32>],
    edges: &[(usize, usize, usize)],
) -> String {
    let mut out = format!("digraph {} {{\n", quote(title));
    for (i, m) in nodes.iter().enumerate() {
        let marked: Vec<String> = m
            .iter()
            .zip(&net.places)
            .filter(|(v, _)| **v > 0)
            .map(|(&v, p)| match v {
                1 => p.id.clone(),
                OMEGA => format!("{}:ω", p.id),
                v => format!("{}:{v}", p.id),
            })
            .collect();
        let style = if i == 0 { ", style=bold" } else { "" };
        let _ = writeln!(
            out,
            "  s{i} [shape=box{style}, label={}];",
            quote(&marked.join("\n"))
        );
    }
    for &(from, t, to) in edges {
        let _ = writeln!(
            out,
            "  s{from} -> s{to} [label={}];",
            quote(&net.transitions[t].id)
        );
    }
    out.push_str("}\n");
    out
}
