//! Petri nets for `vl`: the formalism the thesis designs every lab in.
//!
//! The model and its firing rule (`net`; the session supervisor in
//! `vl-core` runs it live), PNML in and out (`pnml`), statecharts to nets
//! (`scxml`), the reachability graph (`explore`) and the properties read
//! off it (`analysis`), or read during a search that keeps no graph
//! (`onthefly`), the state space counted on several threads (`frontier`),
//! both over tables of packed markings (`markings`), Karp–Miller
//! coverability (`coverability`), P- and T-invariants (`invariants`),
//! composition (`compose`), controller synthesis (`control`), pictures
//! (`dot`), and benchmarks on the Model Checking Contest's models (`bench`,
//! measuring the heap through `vl-report`'s counting allocator). What each
//! analysis found, in the net's own names, is a report (`report`) people
//! read as a `vl-report` table and programs as JSON. Modules are private; what other crates
//! use is re-exported here.
//!
//! In detail:
//!
//! - modules: the thesis's methodology as a library: the net model with
//!   weights, inhibitor arcs, capacities and labels (`net`), PNML in/out
//!   (`pnml`), SCXML statecharts to nets (`scxml`), the reachability graph
//!   (`explore`), and the properties read off it (`analysis`) or during a
//!   depth-first search that keeps no graph (`onthefly`), the states counted
//!   on several threads (`frontier`), both over tables of packed markings
//!   mapped from the system (`markings`), Karp–Miller coverability
//!   (`coverability`), minimal P/T-invariants (`invariants`), synchronous
//!   composition and parallel place fusion (`compose`), controller synthesis
//!   by monitor places and inhibitor arcs (`control`), Graphviz pictures
//!   (`dot`), the corpus manifest and one model's benchmark (`bench`)

mod analysis;
mod bench;
mod compose;
mod control;
mod coverability;
mod dot;
mod explore;
mod frontier;
mod invariants;
mod layout;
mod linalg;
mod lines;
mod liveness;
mod markings;
mod net;
mod onthefly;
mod pnml;
mod report;
mod scxml;
mod verdict;

pub use analysis::{Analysis, analyze, analyze_net, firing_sequence, incidence_rank, no_way_back};
pub use bench::{
    BenchLine, BenchReport, BenchRow, CorpusModel, Manifest, ManifestError, bench_model,
};
pub use compose::{ComposeError, compose, fuse_parallel_places};
pub use control::{Added, Constraint, ControlError, Limits, synthesize};
pub use coverability::{Coverability, CoverabilityError, OMEGA, coverability};
pub use dot::{RenderError, graph_to_dot, graphviz_available, net_to_dot, render_svg};
pub use explore::{Bounds, ExploreError, Options, Progress, StateCount, StateSpace, explore};
pub use frontier::count_states;
pub use invariants::{
    Invariant, TooManyInvariants, is_conservative, p_invariants, p_rows_within, t_invariants,
};
pub use liveness::Liveness;
pub use net::{
    Arc, ArcKind, Marking, MarkingDisplay, Net, NetError, Place, PlaceId, Transition, TransitionId,
};
pub use pnml::{PnmlError, from_pnml, to_pnml};
pub use report::{
    AnalysisReport, Cost, CoverabilityReport, InvariantsReport, StatesReport, Tokens,
};
pub use scxml::{ScxmlError, from_scxml};
pub use verdict::{NetVerdict, verdict};
