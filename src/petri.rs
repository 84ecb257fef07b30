//! `vl petri …`: the thesis's methodology as commands — analyse nets (and
//! later compose them and synthesise their controllers).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use clap::Subcommand;
use serde::Serialize;
use vl_petri::compose::{compose, fuse_parallel_places};
use vl_petri::control::{Added, Constraint, ControlError, Limits, synthesize};
use vl_petri::invariants::{
    Invariant, TooManyInvariants, is_conservative, p_invariants, t_invariants,
};
use vl_petri::scxml::from_scxml;
use vl_petri::{
    Coverability, CoverabilityError, ExploreError, Net, OMEGA, Options, Progress, StateSpace,
    analyze, coverability, explore, from_pnml, graph_to_dot, net_to_dot, to_pnml,
};

use crate::alloc::{peak_bytes, reset_peak};
use crate::{BadInput, read_input};

#[derive(Subcommand)]
pub enum PetriCommand {
    /// Explore the reachability graph and report boundedness, safeness,
    /// deadlocks, liveness, reversibility and the flow-basis dimensions.
    Analyze {
        /// The net, as PNML.
        net: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Stop exploring after this many states.
        #[arg(long, default_value_t = 100_000_000)]
        max_states: usize,
    },
    /// Karp–Miller coverability: is the net bounded, which places are not,
    /// and the maximal ω-markings that cover every reachable marking.
    Coverability {
        net: PathBuf,
        #[arg(long)]
        json: bool,
        /// Also write the coverability graph as Graphviz DOT to this file.
        #[arg(long)]
        dot: Option<PathBuf>,
        /// Give up past this many graph nodes.
        #[arg(long, default_value_t = 10_000_000)]
        max_nodes: usize,
    },
    /// Minimal semi-positive P- and T-invariants (Farkas / Martinez–Silva).
    Invariants {
        net: PathBuf,
        #[arg(long)]
        json: bool,
        /// Give up when the algorithm holds more rows than this.
        #[arg(long, default_value_t = 200_000)]
        max_rows: usize,
    },
    /// Compose nets: transitions with the same label in different nets fire
    /// together (synchronous composition).
    Compose {
        /// Two or more nets.
        #[arg(required = true, num_args = 2..)]
        nets: Vec<PathBuf>,
        /// Then fuse places with identical arcs and marking (Murata).
        #[arg(long)]
        fuse_parallel_places: bool,
        /// Where to write the composed net (PNML).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Add controller places and arcs that enforce constraints on the net:
    /// 'p1 + 2*p3 <= 1' by a monitor place, 'if p2 then not t4' by an inhibitor arc.
    Control {
        net: PathBuf,
        /// A constraint; repeat for several.
        #[arg(long = "constraint", required = true)]
        constraints: Vec<String>,
        /// Transitions the controller may not disable (comma-separated).
        #[arg(long, value_delimiter = ',')]
        uncontrollable: Vec<String>,
        /// Transitions the controller cannot observe (comma-separated).
        #[arg(long, value_delimiter = ',')]
        unobservable: Vec<String>,
        /// Where to write the controlled net (PNML).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Turn a UML statechart (SCXML) into a Petri net: a place per state, a
    /// transition per statechart transition labelled with its event.
    FromScxml {
        chart: PathBuf,
        /// Where to write the net (PNML).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Time state-space exploration on the corpus's large models against the
    /// figures TAPAAL's verifypn 3.1.1 recorded on this kind of machine.
    Bench {
        /// The corpus directory (with manifest.csv).
        #[arg(long, default_value = "tests/petri-corpus")]
        corpus: PathBuf,
        /// Which tier of models: small, medium or large.
        #[arg(long, default_value = "large")]
        tier: String,
        /// Only these models (repeatable).
        #[arg(long = "model")]
        models: Vec<String>,
        #[arg(long)]
        json: bool,
    },
    /// Print the net, or its reachability graph, as Graphviz DOT.
    Dot {
        net: PathBuf,
        /// Draw the reachability graph instead of the net.
        #[arg(long)]
        reachability: bool,
        /// Refuse reachability graphs larger than this.
        #[arg(long, default_value_t = 10_000)]
        max_states: usize,
    },
}

/// Rows the Farkas algorithm may hold while `analyze` decides conservativeness.
const CONSERVATIVE_ROWS: usize = 20_000;

/// Nodes the boundedness pre-check of `analyze` may build before leaving
/// the question to full exploration.
const QUICK_COVERABILITY_NODES: usize = 100_000;

pub fn run(command: PetriCommand) -> Result<ExitCode> {
    match command {
        PetriCommand::Analyze {
            net,
            json,
            max_states,
        } => analyze_command(&net, json, max_states),
        PetriCommand::Coverability {
            net,
            json,
            dot,
            max_nodes,
        } => coverability_command(&net, json, dot.as_deref(), max_nodes),
        PetriCommand::Invariants {
            net,
            json,
            max_rows,
        } => invariants_command(&net, json, max_rows),
        PetriCommand::Compose {
            nets,
            fuse_parallel_places,
            output,
        } => compose_command(&nets, fuse_parallel_places, &output),
        PetriCommand::Control {
            net,
            constraints,
            uncontrollable,
            unobservable,
            output,
        } => control_command(&net, &constraints, uncontrollable, unobservable, &output),
        PetriCommand::Bench {
            corpus,
            tier,
            models,
            json,
        } => bench_command(&corpus, &tier, &models, json),
        PetriCommand::FromScxml { chart, output } => from_scxml_command(&chart, &output),
        PetriCommand::Dot {
            net,
            reachability,
            max_states,
        } => dot_command(&net, reachability, max_states),
    }
}

/// Reads a PNML file; any problem with it is the user's input, exit code 2.
fn load(path: &Path) -> Result<Net> {
    let text = read_input(path)?;
    Ok(from_pnml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?)
}

/// `vl petri analyze --json`: the keys a program reads.
/// Properties that need the full reachability graph are null for an
/// unbounded net.
#[derive(Serialize)]
struct AnalyzeReport {
    places: usize,
    transitions: usize,
    states: Option<usize>,
    edges: Option<usize>,
    bounded: bool,
    max_tokens_in_place: Option<u32>,
    max_tokens_per_marking: Option<u64>,
    safe: bool,
    deadlock: Option<bool>,
    deadlock_trace: Option<Vec<String>>,
    quasi_live: Option<bool>,
    live: Option<bool>,
    reversible: Option<bool>,
    /// Null when the net has too many minimal P-invariants to decide it this way.
    conservative: Option<bool>,
    p_flow_basis_dim: usize,
    t_flow_basis_dim: usize,
    seconds: f64,
    peak_bytes: usize,
}

fn analyze_command(path: &Path, json: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    // Karp–Miller settles boundedness first when it can do so cheaply: an
    // unbounded net would otherwise explore until --max-states.
    if let Ok(c) = coverability(&net, QUICK_COVERABILITY_NODES)
        && !c.bounded()
    {
        return report_unbounded(&net, &c, started, json);
    }
    let space = explore_with_progress(&net, path, max_states)?;
    let a = analyze(&net, &space);
    let report = AnalyzeReport {
        places: a.places,
        transitions: a.transitions,
        states: Some(a.states),
        edges: Some(a.edges),
        bounded: a.bounded,
        max_tokens_in_place: Some(a.max_tokens_in_place),
        max_tokens_per_marking: Some(a.max_tokens_per_marking),
        safe: a.safe,
        deadlock: Some(a.deadlock),
        deadlock_trace: a.deadlock_trace.clone(),
        quasi_live: Some(a.quasi_live),
        live: Some(a.live),
        reversible: Some(a.reversible),
        conservative: conservative(&net),
        p_flow_basis_dim: a.p_flow_basis_dim,
        t_flow_basis_dim: a.t_flow_basis_dim,
        seconds: started.elapsed().as_secs_f64(),
        peak_bytes: peak_bytes(),
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let yes = |b: bool| if b { "yes" } else { "no" };
    let trace = match &a.deadlock_trace {
        Some(t) if t.is_empty() => "the initial marking is dead".to_owned(),
        Some(t) => t.join(" "),
        None => "–".to_owned(),
    };
    let rows = [
        (
            "net",
            format!(
                "{} ({} places, {} transitions)",
                net.id, a.places, a.transitions
            ),
        ),
        ("states", a.states.to_string()),
        ("edges", a.edges.to_string()),
        (
            "bounded",
            format!(
                "{} (at most {} tokens in a place, {} in a marking)",
                yes(a.bounded),
                a.max_tokens_in_place,
                a.max_tokens_per_marking
            ),
        ),
        ("safe", yes(a.safe).to_owned()),
        ("deadlock", yes(a.deadlock).to_owned()),
        ("  reached by", trace),
        ("quasi-live", yes(a.quasi_live).to_owned()),
        ("live", yes(a.live).to_owned()),
        ("  not L4", not_live(&net, &a.liveness)),
        ("reversible", yes(a.reversible).to_owned()),
        ("P-flow basis", format!("dimension {}", a.p_flow_basis_dim)),
        ("T-flow basis", format!("dimension {}", a.t_flow_basis_dim)),
        (
            "time",
            format!(
                "{:.3} s, {} states/s",
                report.seconds,
                (a.states as f64 / report.seconds.max(1e-9)) as u64
            ),
        ),
        (
            "memory",
            format!(
                "{:.1} MB peak, {} bytes per marking",
                report.peak_bytes as f64 / 1e6,
                space.bytes_per_marking()
            ),
        ),
    ];
    for (name, value) in rows {
        println!("{name:<14} {value}");
    }
    Ok(ExitCode::SUCCESS)
}

/// Explores the reachability graph, showing progress on a terminal.
fn explore_with_progress(net: &Net, path: &Path, max_states: usize) -> Result<StateSpace> {
    let show_progress = std::io::stderr().is_terminal();
    let mut report_progress = |p: Progress| {
        eprint!(
            "\r{:>12} states {:>14} edges {:>10.0} states/s",
            p.states,
            p.edges,
            p.states as f64 / p.elapsed.as_secs_f64().max(1e-9)
        );
    };
    let options = Options {
        max_states,
        progress: show_progress.then_some(&mut report_progress as &mut dyn FnMut(Progress)),
    };
    let result = explore(net, options);
    if show_progress {
        eprint!("\r{:78}\r", "");
    }
    match result {
        Ok(space) => Ok(space),
        Err(e @ ExploreError::TooManyStates { .. }) => {
            anyhow::bail!("{}: {e}; raise --max-states to go on", path.display())
        }
        Err(e) => anyhow::bail!("{}: {e}", path.display()),
    }
}

fn report_unbounded(net: &Net, c: &Coverability, started: Instant, json: bool) -> Result<ExitCode> {
    let unbounded: Vec<&str> = c
        .unbounded
        .iter()
        .map(|&p| net.places[p].id.as_str())
        .collect();
    if json {
        let report = AnalyzeReport {
            places: net.places.len(),
            transitions: net.transitions.len(),
            states: None,
            edges: None,
            bounded: false,
            max_tokens_in_place: None,
            max_tokens_per_marking: None,
            safe: false,
            deadlock: None,
            deadlock_trace: None,
            quasi_live: None,
            live: None,
            reversible: None,
            conservative: conservative(net),
            p_flow_basis_dim: net.places.len() - vl_petri::incidence_rank(net),
            t_flow_basis_dim: net.transitions.len() - vl_petri::incidence_rank(net),
            seconds: started.elapsed().as_secs_f64(),
            peak_bytes: peak_bytes(),
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{:<14} {} ({} places, {} transitions)",
            "net",
            net.id,
            net.places.len(),
            net.transitions.len()
        );
        println!(
            "{:<14} no: {} can grow without limit",
            "bounded",
            unbounded.join(", ")
        );
        println!("{:<14} see `vl petri coverability` for the ω-markings", "");
    }
    Ok(ExitCode::SUCCESS)
}

/// An ω-marking as JSON: place id → count or "ω", empty places left out.
fn omega_marking(net: &Net, m: &[u32]) -> serde_json::Map<String, serde_json::Value> {
    m.iter()
        .zip(&net.places)
        .filter(|(v, _)| **v > 0)
        .map(|(&v, p)| {
            let value = if v == OMEGA {
                serde_json::json!("ω")
            } else {
                serde_json::json!(v)
            };
            (p.id.clone(), value)
        })
        .collect()
}

fn coverability_command(
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
        std::fs::write(file, picture)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", file.display()))?;
    }
    let unbounded: Vec<String> = c
        .unbounded
        .iter()
        .map(|&p| net.places[p].id.clone())
        .collect();
    let maximal: Vec<_> = c
        .maximal()
        .into_iter()
        .map(|m| omega_marking(&net, m))
        .collect();
    if json {
        let report = serde_json::json!({
            "bounded": c.bounded(),
            "unbounded_places": unbounded,
            "maximal": maximal,
            "nodes": c.nodes.len(),
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{:<18} {}",
            "bounded",
            if c.bounded() { "yes" } else { "no" }
        );
        println!(
            "{:<18} {}",
            "unbounded places",
            if unbounded.is_empty() {
                "–".to_owned()
            } else {
                unbounded.join(", ")
            }
        );
        println!("{:<18} {}", "graph nodes", c.nodes.len());
        println!("maximal markings:");
        for m in &maximal {
            let cells: Vec<String> = m
                .iter()
                .map(|(p, v)| {
                    format!(
                        "{p}={}",
                        v.as_str().map_or_else(|| v.to_string(), str::to_owned)
                    )
                })
                .collect();
            println!("  {{{}}}", cells.join(", "));
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn dot_command(path: &Path, reachability: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    if !reachability {
        print!("{}", net_to_dot(&net));
        return Ok(ExitCode::SUCCESS);
    }
    let space = explore_with_progress(&net, path, max_states)?;
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

/// Whether a positive weighting of all places is invariant, if the minimal
/// P-invariants can be listed.
fn conservative(net: &Net) -> Option<bool> {
    let invariants = p_invariants(net, CONSERVATIVE_ROWS).ok()?;
    Some(is_conservative(net.places.len(), &invariants))
}

fn invariants_command(path: &Path, json: bool, max_rows: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let describe = |e: TooManyInvariants| {
        anyhow::anyhow!("{}: {e}; raise --max-rows to go on", path.display())
    };
    let p = p_invariants(&net, max_rows).map_err(describe)?;
    let t = t_invariants(&net, max_rows).map_err(describe)?;
    let rank = vl_petri::incidence_rank(&net);
    let place_ids: Vec<&str> = net.places.iter().map(|p| p.id.as_str()).collect();
    let transition_ids: Vec<&str> = net.transitions.iter().map(|t| t.id.as_str()).collect();
    let as_map = |inv: &Invariant, ids: &[&str]| -> serde_json::Map<String, serde_json::Value> {
        inv.iter()
            .map(|&(i, k)| (ids[i].to_owned(), serde_json::json!(k)))
            .collect()
    };
    if json {
        let report = serde_json::json!({
            "p_invariants": p.iter().map(|i| as_map(i, &place_ids)).collect::<Vec<_>>(),
            "t_invariants": t.iter().map(|i| as_map(i, &transition_ids)).collect::<Vec<_>>(),
            "p_flow_basis_dim": net.places.len() - rank,
            "t_flow_basis_dim": net.transitions.len() - rank,
            "conservative": is_conservative(net.places.len(), &p),
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let sum = |inv: &Invariant, ids: &[&str]| -> String {
        inv.iter()
            .map(|&(i, k)| {
                if k == 1 {
                    ids[i].to_owned()
                } else {
                    format!("{k}·{}", ids[i])
                }
            })
            .collect::<Vec<_>>()
            .join(" + ")
    };
    println!(
        "{} minimal P-invariants (P-flow basis dimension {}):",
        p.len(),
        net.places.len() - rank
    );
    for inv in &p {
        let m0: u64 = inv
            .iter()
            .map(|&(i, k)| k * u64::from(net.places[i].initial))
            .sum();
        println!("  {} = {m0}", sum(inv, &place_ids));
    }
    println!(
        "{} minimal T-invariants (T-flow basis dimension {}):",
        t.len(),
        net.transitions.len() - rank
    );
    for inv in &t {
        println!("  {}", sum(inv, &transition_ids));
    }
    println!(
        "conservative: {}",
        if is_conservative(net.places.len(), &p) {
            "yes"
        } else {
            "no"
        }
    );
    Ok(ExitCode::SUCCESS)
}

fn control_command(
    path: &Path,
    constraints: &[String],
    uncontrollable: Vec<String>,
    unobservable: Vec<String>,
    output: &Path,
) -> Result<ExitCode> {
    let plant = load(path)?;
    let bad = |e: ControlError| BadInput(format!("{}: {e}", path.display()));
    let constraints = constraints
        .iter()
        .map(|c| Constraint::parse(c))
        .collect::<Result<Vec<_>, _>>()
        .map_err(bad)?;
    let limits = Limits {
        uncontrollable,
        unobservable,
    };
    let (net, added) = synthesize(&plant, &constraints, &limits).map_err(bad)?;
    write_file(output, &to_pnml(&net))?;
    for a in &added {
        match a {
            Added::Monitor {
                place,
                initial,
                enforced,
            } => {
                println!("monitor place {place:<12} m0 = {initial:<4} enforces {enforced}")
            }
            Added::Inhibitor { place, transition } => {
                println!("inhibitor arc {place} ⊸ {transition}")
            }
        }
    }
    println!("wrote {}", output.display());
    Ok(ExitCode::SUCCESS)
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

fn compose_command(paths: &[PathBuf], fuse: bool, output: &Path) -> Result<ExitCode> {
    let nets = paths.iter().map(|p| load(p)).collect::<Result<Vec<_>>>()?;
    let mut net = compose(&nets)?;
    let before = net.places.len();
    if fuse {
        net = fuse_parallel_places(&net);
    }
    write_file(output, &to_pnml(&net))?;
    let fused = net
        .transitions
        .iter()
        .filter(|t| t.id.contains('|'))
        .count();
    println!(
        "{} places ({} fused away), {} transitions ({fused} synchronised)",
        net.places.len(),
        before - net.places.len(),
        net.transitions.len()
    );
    println!("wrote {}", output.display());
    Ok(ExitCode::SUCCESS)
}

fn from_scxml_command(path: &Path, output: &Path) -> Result<ExitCode> {
    let text = read_input(path)?;
    let net = from_scxml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
    write_file(output, &to_pnml(&net))?;
    println!(
        "{} places (states), {} transitions; wrote {}",
        net.places.len(),
        net.transitions.len(),
        output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// One model's benchmark figures.
#[derive(Serialize)]
struct BenchRow {
    model: String,
    states: usize,
    edges: usize,
    certified_states: usize,
    certified_edges: usize,
    explore_seconds: f64,
    analyze_seconds: f64,
    states_per_second: f64,
    store_bytes_per_state: f64,
    graph_bytes_per_state: f64,
    peak_bytes: usize,
    verifypn_seconds: Option<f64>,
    /// verifypn's time over ours for exploring: above 1 means we are faster.
    speedup_vs_verifypn: Option<f64>,
}

fn bench_command(corpus: &Path, tier: &str, only: &[String], json: bool) -> Result<ExitCode> {
    let manifest = corpus.join("manifest.csv");
    let text = read_input(&manifest)?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| BadInput(format!("{} has no column {name}", manifest.display())))
    };
    let (c_model, c_tier, c_pnml, c_states, c_edges, c_vp) = (
        column("model")?,
        column("tier")?,
        column("pnml")?,
        column("states")?,
        column("rg_edges")?,
        column("verifypn_wall_s")?,
    );
    let mut rows = Vec::new();
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        let name = cells[c_model];
        if cells[c_tier] != tier || (!only.is_empty() && !only.iter().any(|m| m == name)) {
            continue;
        }
        let net = load(&corpus.join(cells[c_pnml]))?;
        if !json {
            eprint!("{name} … ");
        }
        reset_peak();
        let started = Instant::now();
        let space =
            explore(&net, Options::default()).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        let explore_seconds = started.elapsed().as_secs_f64();
        let analyzed = Instant::now();
        let _ = analyze(&net, &space);
        let analyze_seconds = analyzed.elapsed().as_secs_f64();
        let states = space.states();
        let verifypn_seconds = cells[c_vp].parse::<f64>().ok().filter(|&v| v > 0.0);
        rows.push(BenchRow {
            model: name.to_owned(),
            states,
            edges: space.edges(),
            certified_states: cells[c_states].parse().unwrap_or(0),
            certified_edges: cells[c_edges].parse().unwrap_or(0),
            explore_seconds,
            analyze_seconds,
            states_per_second: states as f64 / explore_seconds,
            store_bytes_per_state: space.store_bytes() as f64 / states as f64,
            graph_bytes_per_state: space.graph_bytes() as f64 / states as f64,
            peak_bytes: peak_bytes(),
            verifypn_seconds,
            speedup_vs_verifypn: verifypn_seconds.map(|v| v / explore_seconds),
        });
        if !json {
            eprintln!("{explore_seconds:.2} s");
        }
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "{:<28} {:>10} {:>5} {:>9} {:>11} {:>9} {:>9} {:>9} {:>9} {:>8}",
        "model",
        "states",
        "ok",
        "explore s",
        "states/s",
        "store B/s",
        "graph B/s",
        "analyze s",
        "verifypn",
        "speedup"
    );
    for r in &rows {
        println!(
            "{:<28} {:>10} {:>5} {:>9.2} {:>11.0} {:>9.1} {:>9.1} {:>9.2} {:>9} {:>8}",
            r.model,
            r.states,
            if r.states == r.certified_states {
                "yes"
            } else {
                "NO"
            },
            r.explore_seconds,
            r.states_per_second,
            r.store_bytes_per_state,
            r.graph_bytes_per_state,
            r.analyze_seconds,
            r.verifypn_seconds
                .map_or("–".to_owned(), |v| format!("{v:.2} s")),
            r.speedup_vs_verifypn
                .map_or("–".to_owned(), |v| format!("{v:.2}×")),
        );
    }
    println!("ok: states and edges equal the certified counts. Single thread; verifypn 3.1.1's");
    println!(
        "explicit engine times were measured on this kind of machine and come from the manifest."
    );
    Ok(ExitCode::SUCCESS)
}

/// The transitions that are not live, with their liveness level.
fn not_live(net: &Net, levels: &[vl_petri::Liveness]) -> String {
    let weak: Vec<String> = levels
        .iter()
        .zip(&net.transitions)
        .filter(|(l, _)| **l != vl_petri::Liveness::L4)
        .map(|(l, t)| format!("{} {l:?}", t.id))
        .collect();
    match weak.len() {
        0 => "–".to_owned(),
        n if n > 12 => format!("{} … and {} more", weak[..12].join(", "), n - 12),
        _ => weak.join(", "),
    }
}
