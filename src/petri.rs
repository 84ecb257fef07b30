//! `vl petri …`: the thesis's methodology as commands — statecharts to
//! nets, analysis, composition and controller synthesis.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Subcommand;
use serde::Serialize;
use vl_petri::{
    Added, BenchRow, Constraint, ControlError, Coverability, CoverabilityError, ExploreError,
    Invariant, Limits, Manifest, Net, OMEGA, Options, Progress, StateSpace, TooManyInvariants,
    analyze_net, bench_model, compose, count_states, coverability, explore, from_pnml, from_scxml,
    fuse_parallel_places, graph_to_dot, is_conservative, net_to_dot, p_invariants, p_rows_within,
    synthesize, t_invariants, to_pnml,
};

use crate::BadInput;
use crate::alloc::{Counting, peak_bytes, peak_resident_bytes};
use crate::report::{Report, Table, count, emit, yes};
use crate::shipped::{CORPUS_MANIFEST, corpus_model, read_input};

#[derive(Subcommand)]
pub(crate) enum PetriCommand {
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
    /// Explore only, keeping no edge: count the reachable markings and the
    /// firings between them, and each place's bound (what `verifypn -e` reports).
    States {
        /// The net, as PNML.
        net: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Stop exploring after this many states.
        #[arg(long, default_value_t = 100_000_000)]
        max_states: usize,
        /// Threads to explore on (the counts are the same on any number).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=256))]
        threads: u16,
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
    /// Time exploring and analysing the corpus's large models, in this
    /// process and as a whole `vl petri analyze` process, beside the figures
    /// recorded for TAPAAL's verifypn 3.1.1 (recorded, not measured here).
    Bench {
        /// A corpus directory (with manifest.csv); the large models are
        /// built in, the small and medium ones are in tests/petri-corpus.
        #[arg(long)]
        corpus: Option<PathBuf>,
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

pub(crate) fn run(command: PetriCommand) -> Result<ExitCode> {
    match command {
        PetriCommand::Analyze {
            net,
            json,
            max_states,
        } => analyze_command(&net, json, max_states),
        PetriCommand::States {
            net,
            json,
            max_states,
            threads,
        } => states_command(&net, json, max_states, threads.into()),
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
        } => bench_command(corpus.as_deref(), &tier, &models, json),
        PetriCommand::FromScxml { chart, output } => from_scxml_command(&chart, &output),
        PetriCommand::Dot {
            net,
            reachability,
            max_states,
        } => dot_command(&net, reachability, max_states),
    }
}

/// Reads a PNML file (or a shipped example net); any problem with it is
/// the user's input, exit code 2.
fn load(path: &Path) -> Result<Net> {
    let text = read_input(path)?;
    Ok(from_pnml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?)
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

/// `vl petri analyze`: the keys a program reads. Properties that need the
/// full reachability graph are null for an unbounded net.
#[derive(Serialize)]
struct AnalyzeReport {
    net: String,
    places: usize,
    transitions: usize,
    states: Option<usize>,
    edges: Option<usize>,
    bounded: bool,
    /// The places that can grow without limit (Karp–Miller's ω).
    unbounded_places: Vec<String>,
    max_tokens_in_place: Option<u32>,
    max_tokens_per_marking: Option<u64>,
    safe: bool,
    deadlock: Option<bool>,
    deadlock_trace: Option<Vec<String>>,
    quasi_live: Option<bool>,
    live: Option<bool>,
    /// Transitions below L4, with their level.
    not_live: Vec<String>,
    reversible: Option<bool>,
    /// Null when the net has too many minimal P-invariants to decide it this way.
    conservative: Option<bool>,
    p_flow_basis_dim: usize,
    t_flow_basis_dim: usize,
    seconds: f64,
    /// The most heap bytes live at once.
    peak_heap_bytes: usize,
    /// The process's peak resident memory.
    peak_resident_bytes: usize,
    #[serde(skip)]
    bytes_per_marking: usize,
}

/// When and where the manifest's verifypn figures were recorded.
const VERIFYPN_RECORDED: &str = "recorded 2026-11-21, Debian 12, 2 cores";

/// Rows the Farkas algorithm may hold while `analyze` decides
/// conservativeness, and the memory it may take: less than exploring a
/// large net takes, so the verdict never sets the peak.
const CONSERVATIVE_ROWS: usize = 20_000;
const CONSERVATIVE_BYTES: usize = 32 << 20;

/// Nodes the boundedness pre-check of `analyze` may build before leaving
/// the question to full exploration: enough for a small unbounded net to be
/// named at once, little enough (a fraction of a second) not to weigh on a
/// large bounded one. A larger net stops at --max-states, which says where
/// to look.
const QUICK_COVERABILITY_NODES: usize = 10_000;

fn analyze_command(path: &Path, json: bool, max_states: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    let rank = vl_petri::incidence_rank(&net);
    let mut report = AnalyzeReport {
        net: net.id.clone(),
        places: net.places.len(),
        transitions: net.transitions.len(),
        states: None,
        edges: None,
        bounded: false,
        unbounded_places: Vec::new(),
        max_tokens_in_place: None,
        max_tokens_per_marking: None,
        safe: false,
        deadlock: None,
        deadlock_trace: None,
        quasi_live: None,
        live: None,
        not_live: Vec::new(),
        reversible: None,
        conservative: conservative(&net),
        p_flow_basis_dim: net.places.len() - rank,
        t_flow_basis_dim: net.transitions.len() - rank,
        seconds: 0.0,
        peak_heap_bytes: 0,
        peak_resident_bytes: 0,
        bytes_per_marking: 0,
    };
    // Karp–Miller settles boundedness first when it can do so cheaply: an
    // unbounded net would otherwise explore until --max-states. A
    // conservative net (a P-invariant weighs every place) is bounded
    // already, and needs no such check.
    let quick = match report.conservative {
        Some(true) => None,
        _ => coverability(&net, QUICK_COVERABILITY_NODES).ok(),
    };
    match quick {
        Some(c) if !c.bounded() => {
            report.unbounded_places = place_ids(&net, &c.unbounded);
        }
        _ => {
            let a = with_progress(path, max_states, |options| analyze_net(&net, options))?;
            report.states = Some(a.states);
            report.edges = Some(a.edges);
            report.bounded = a.bounded;
            report.max_tokens_in_place = Some(a.max_tokens_in_place);
            report.max_tokens_per_marking = Some(a.max_tokens_per_marking);
            report.safe = a.safe;
            report.deadlock = Some(a.deadlock);
            report.deadlock_trace = a.deadlock_trace;
            report.quasi_live = Some(a.quasi_live);
            report.live = Some(a.live);
            report.reversible = Some(a.reversible);
            report.not_live = a
                .liveness
                .iter()
                .zip(&net.transitions)
                .filter(|(l, _)| **l != vl_petri::Liveness::L4)
                .map(|(l, t)| format!("{} {l:?}", t.id))
                .collect();
            report.bytes_per_marking = a.bytes_per_marking;
        }
    }
    report.seconds = started.elapsed().as_secs_f64();
    report.peak_heap_bytes = peak_bytes();
    report.peak_resident_bytes = peak_resident_bytes();
    emit(&report, json)?;
    Ok(ExitCode::SUCCESS)
}

impl Report for AnalyzeReport {
    fn table(&self) -> Table {
        let net = format!(
            "{} ({}, {})",
            self.net,
            count(self.places as u64, "place", "places"),
            count(self.transitions as u64, "transition", "transitions")
        );
        let (Some(states), Some(edges)) = (self.states, self.edges) else {
            return Table::pairs([
                ("net", net),
                (
                    "bounded",
                    format!(
                        "no: {} can grow without limit",
                        self.unbounded_places.join(", ")
                    ),
                ),
            ])
            .note("see `vl petri coverability` for the ω-markings");
        };
        let maybe = |b: Option<bool>| b.map_or("–", yes).to_owned();
        let trace = match &self.deadlock_trace {
            Some(t) if t.is_empty() => "the initial marking is dead".to_owned(),
            Some(t) => t.join(" "),
            None => "–".to_owned(),
        };
        let not_live = match self.not_live.len() {
            0 => "–".to_owned(),
            n if n > 12 => format!("{} … and {} more", self.not_live[..12].join(", "), n - 12),
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
            .chain(cost_rows(
                states,
                self.seconds,
                self.peak_heap_bytes,
                self.peak_resident_bytes,
                self.bytes_per_marking,
            )),
        )
    }
}

/// Explores the reachability graph, showing progress on a terminal.
fn explore_with_progress(net: &Net, path: &Path, max_states: usize) -> Result<StateSpace> {
    with_progress(path, max_states, |options| explore(net, options))
}

/// Runs a search (`explore` or `count_states`) with `--max-states`, its
/// progress on a terminal, and its stops said in the user's terms.
fn with_progress<T>(
    path: &Path,
    max_states: usize,
    search: impl FnOnce(Options) -> Result<T, ExploreError>,
) -> Result<T> {
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
    let result = search(options);
    if show_progress {
        eprint!("\r{:78}\r", "");
    }
    match result {
        Ok(found) => Ok(found),
        Err(e @ ExploreError::TooManyStates { .. }) => {
            anyhow::bail!(
                "{}: {e}; raise --max-states to go on (if the net may be unbounded, `vl petri coverability` names the places that grow)",
                path.display()
            )
        }
        Err(e) => anyhow::bail!("{}: {e}", path.display()),
    }
}

/// `vl petri states`: what exploration alone finds, as `verifypn -e` reports it.
#[derive(Serialize)]
struct StatesReport {
    net: String,
    places: usize,
    transitions: usize,
    states: usize,
    /// Firings between markings (verifypn's "discovered states" less one).
    edges: usize,
    max_tokens_in_place: u32,
    max_tokens_per_marking: u64,
    /// Each place's bound, by place id.
    place_bounds: std::collections::BTreeMap<String, u32>,
    seconds: f64,
    peak_heap_bytes: usize,
    peak_resident_bytes: usize,
    bytes_per_marking: usize,
}

fn states_command(path: &Path, json: bool, max_states: usize, threads: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let started = Instant::now();
    let found = with_progress(path, max_states, |options| {
        count_states(&net, options, threads)
    })?;
    let report = StatesReport {
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
        seconds: started.elapsed().as_secs_f64(),
        peak_heap_bytes: peak_bytes(),
        peak_resident_bytes: peak_resident_bytes(),
        bytes_per_marking: found.bytes_per_marking,
    };
    emit(&report, json)?;
    Ok(ExitCode::SUCCESS)
}

impl Report for StatesReport {
    fn table(&self) -> Table {
        Table::pairs(
            [
                (
                    "net",
                    format!(
                        "{} ({}, {})",
                        self.net,
                        count(self.places as u64, "place", "places"),
                        count(self.transitions as u64, "transition", "transitions")
                    ),
                ),
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
            .chain(cost_rows(
                self.states,
                self.seconds,
                self.peak_heap_bytes,
                self.peak_resident_bytes,
                self.bytes_per_marking,
            )),
        )
        .note("each place's bound: --json")
    }
}

/// The time and memory rows of `analyze` and `states`.
fn cost_rows(
    states: usize,
    seconds: f64,
    peak_heap_bytes: usize,
    peak_resident_bytes: usize,
    bytes_per_marking: usize,
) -> [(&'static str, String); 2] {
    [
        (
            "time",
            format!(
                "{seconds:.3} s, {} states/s",
                (states as f64 / seconds.max(1e-9)) as u64
            ),
        ),
        (
            "memory",
            format!(
                "{:.1} MB heap peak, {:.1} MB resident peak, {} per marking",
                peak_heap_bytes as f64 / 1e6,
                peak_resident_bytes as f64 / 1e6,
                count(bytes_per_marking as u64, "byte", "bytes")
            ),
        ),
    ]
}

fn place_ids(net: &Net, places: &[usize]) -> Vec<String> {
    places.iter().map(|&p| net.places[p].id.clone()).collect()
}

/// An ω-marking: place id → count or "ω", empty places left out.
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
        write_file(file, &picture)?;
    }
    emit(&CoverabilityReport::new(&net, &c), json)?;
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
    let rows = CONSERVATIVE_ROWS.min(p_rows_within(net, CONSERVATIVE_BYTES));
    let invariants = p_invariants(net, rows).ok()?;
    Some(is_conservative(net.places.len(), &invariants))
}

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

fn invariants_command(path: &Path, json: bool, max_rows: usize) -> Result<ExitCode> {
    let net = load(path)?;
    let describe = |e: TooManyInvariants| {
        anyhow::anyhow!("{}: {e}; raise --max-rows to go on", path.display())
    };
    let p = p_invariants(&net, max_rows).map_err(describe)?;
    let t = t_invariants(&net, max_rows).map_err(describe)?;
    emit(&InvariantsReport::new(&net, &p, &t), json)?;
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
        "{} ({} fused away), {} ({fused} synchronised)",
        count(net.places.len() as u64, "place", "places"),
        before - net.places.len(),
        count(net.transitions.len() as u64, "transition", "transitions"),
    );
    println!("wrote {}", output.display());
    Ok(ExitCode::SUCCESS)
}

fn from_scxml_command(path: &Path, output: &Path) -> Result<ExitCode> {
    let text = read_input(path)?;
    let net = from_scxml(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
    write_file(output, &to_pnml(&net))?;
    println!(
        "{} (states), {}; wrote {}",
        count(net.places.len() as u64, "place", "places"),
        count(net.transitions.len() as u64, "transition", "transitions"),
        output.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn bench_command(
    corpus: Option<&Path>,
    tier: &str,
    only: &[String],
    json: bool,
) -> Result<ExitCode> {
    let manifest_text = match corpus {
        Some(dir) => read_input(&dir.join("manifest.csv"))?,
        None => CORPUS_MANIFEST.to_owned(),
    };
    let manifest = Manifest::parse(&manifest_text).map_err(|e| BadInput(e.to_string()))?;
    let models: Vec<_> = manifest
        .tier(tier)
        .filter(|m| only.is_empty() || only.iter().any(|name| name == m.name()))
        .collect();
    if models.is_empty() {
        return Err(BadInput(format!(
            "no {tier} model{} in the manifest",
            if only.is_empty() {
                String::new()
            } else {
                format!(" named {}", only.join(", "))
            }
        ))
        .into());
    }
    let mut rows: Vec<BenchLine> = Vec::new();
    for model in models {
        let (net, file) = match corpus {
            Some(dir) => (load(&dir.join(model.pnml()))?, None),
            None => {
                let text = corpus_model(model.pnml()).ok_or_else(|| {
                    BadInput(format!(
                        "{} is not built in (only the large tier is): \
                         give --corpus tests/petri-corpus",
                        model.name()
                    ))
                })?;
                let net = from_pnml(text).map_err(|e| anyhow::anyhow!("{}: {e}", model.name()))?;
                (net, Some(text))
            }
        };
        if !json {
            eprint!("{} … ", model.name());
        }
        let row = bench_model(model, &net, &Counting)
            .map_err(|e| anyhow::anyhow!("{}: {e}", model.name()))?;
        let whole = match (corpus, file) {
            (Some(dir), _) => analyze_process(&dir.join(model.pnml()))?,
            (None, Some(text)) => {
                let path = std::env::temp_dir().join(format!(
                    "vl-bench-{}-{}.pnml",
                    std::process::id(),
                    model.name()
                ));
                std::fs::write(&path, text)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                let whole = analyze_process(&path);
                let _ = std::fs::remove_file(&path);
                whole?
            }
            (None, None) => unreachable!("a built-in model has its text"),
        };
        if !json {
            eprintln!(
                "{:.2} s counting, {:.2} s analysing, {:.2} s analysing as a process",
                row.count_seconds, row.analyze_seconds, whole.0
            );
        }
        rows.push(BenchLine {
            row,
            analyze_process_seconds: whole.0,
            analyze_process_peak_mb: whole.1,
        });
    }
    emit(&rows, json)?;
    Ok(ExitCode::SUCCESS)
}

/// One model's benchmark: exploring and analysing in this process, and
/// `vl petri analyze` on it as a whole process, as a user runs it.
#[derive(Serialize)]
struct BenchLine {
    #[serde(flatten)]
    row: BenchRow,
    /// Wall time of `vl petri analyze MODEL --json`, start to exit.
    analyze_process_seconds: f64,
    /// Its peak resident memory, MB.
    analyze_process_peak_mb: f64,
}

/// Runs `vl petri analyze` on `model` as a separate process: its wall time,
/// s, and its peak resident memory, MB (as it reports it).
fn analyze_process(model: &Path) -> Result<(f64, f64)> {
    let me = std::env::current_exe().context("cannot find the vl binary")?;
    let started = Instant::now();
    let out = std::process::Command::new(me)
        .args(["petri", "analyze", "--json"])
        .arg(model)
        .output()
        .context("cannot run vl petri analyze")?;
    let seconds = started.elapsed().as_secs_f64();
    anyhow::ensure!(
        out.status.success(),
        "vl petri analyze {} failed: {}",
        model.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&out.stdout).context("vl petri analyze printed no JSON")?;
    let peak = report["peak_resident_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6;
    Ok((seconds, peak))
}

impl Report for Vec<BenchLine> {
    fn table(&self) -> Table {
        let mut table = Table::columns(&[
            "model",
            "states",
            "ok",
            "states s",
            "2 threads",
            "states/s",
            "heap MB",
            "B/marking",
            "analyze s",
            "process s",
            "process MB",
            "verifypn s*",
            "verifypn MB*",
        ]);
        for line in self {
            let r = &line.row;
            table.row(vec![
                r.model.clone(),
                r.states.to_string(),
                if r.certified() { "yes" } else { "NO" }.to_owned(),
                format!("{:.2}", r.count_seconds),
                format!(
                    "{:.2} ({:.2}×)",
                    r.count_seconds_on_two,
                    r.count_seconds / r.count_seconds_on_two
                ),
                format!("{:.0}", r.states_per_second),
                format!("{:.0}", r.count_peak_heap_bytes as f64 / 1e6),
                r.bytes_per_marking.to_string(),
                format!("{:.2}", r.analyze_seconds),
                format!("{:.2}", line.analyze_process_seconds),
                format!("{:.0}", line.analyze_process_peak_mb),
                r.verifypn_recorded_seconds
                    .map_or("–".to_owned(), |v| format!("{v:.2}")),
                r.verifypn_recorded_peak_kb
                    .map_or("–".to_owned(), |v| format!("{:.0}", v as f64 / 1e3)),
            ]);
        }
        table
            .note("ok: counting (on one thread and on two) and analysing all found the certified numbers of states and edges.")
            .note("states s, analyze s: `vl petri states` and `vl petri analyze` as jobs in this process, one thread; 2 threads: `vl petri states --threads 2`, and its speed-up; heap MB: the most live at once while counting on one;")
            .note("process s, process MB: `vl petri analyze MODEL --json` as a whole process (wall time, peak resident memory: the analysis maps its memory from the system, outside the heap).")
            .note(format!(
                "* recorded, not measured in this run: TAPAAL verifypn 3.1.1 -e as a whole process on a 2-core machine \
                 like CI's, from the corpus manifest ({VERIFYPN_RECORDED}). Recorded times have differed from \
                 side-by-side runs by -14 % to +40 %, so no ratio is printed: bench/petri_vs_verifypn.sh runs both \
                 side by side"
            ))
    }
}
