//! `vl petri …`: the thesis's methodology as commands — statecharts to
//! nets, analysis, composition and controller synthesis.

mod analyze;
mod bench;
mod compose;
mod control;
mod coverability;
mod dot;
mod from_scxml;
mod invariants;
mod io;
mod states;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;

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
        /// built in, the small and medium ones are in assets/petri-corpus.
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
        } => analyze::analyze_command(&net, json, max_states),
        PetriCommand::States {
            net,
            json,
            max_states,
            threads,
        } => states::states_command(&net, json, max_states, threads.into()),
        PetriCommand::Coverability {
            net,
            json,
            dot,
            max_nodes,
        } => coverability::coverability_command(&net, json, dot.as_deref(), max_nodes),
        PetriCommand::Invariants {
            net,
            json,
            max_rows,
        } => invariants::invariants_command(&net, json, max_rows),
        PetriCommand::Compose {
            nets,
            fuse_parallel_places,
            output,
        } => compose::compose_command(&nets, fuse_parallel_places, &output),
        PetriCommand::Control {
            net,
            constraints,
            uncontrollable,
            unobservable,
            output,
        } => control::control_command(&net, &constraints, uncontrollable, unobservable, &output),
        PetriCommand::Bench {
            corpus,
            tier,
            models,
            json,
        } => bench::bench_command(corpus.as_deref(), &tier, &models, json),
        PetriCommand::FromScxml { chart, output } => {
            from_scxml::from_scxml_command(&chart, &output)
        }
        PetriCommand::Dot {
            net,
            reachability,
            max_states,
        } => dot::dot_command(&net, reachability, max_states),
    }
}
