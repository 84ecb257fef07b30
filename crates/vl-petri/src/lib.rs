//! Petri nets for `vl`: the formalism the thesis designs every lab in.
//!
//! [`net`] holds the model and its firing rule (the session supervisor in
//! `vl-core` runs it live), [`pnml`] moves nets in and out, [`explore`]
//! builds the reachability graph and [`analysis`] reads properties off it;
//! [`coverability`] decides boundedness with Karp–Miller; [`dot`] draws.

pub mod analysis;
pub mod compose;
pub mod control;
pub mod coverability;
pub mod dot;
pub mod explore;
pub mod invariants;
mod linalg;
pub mod net;
pub mod pnml;
pub mod scxml;

pub use analysis::{Analysis, Liveness, analyze, incidence_rank};
pub use coverability::{Coverability, CoverabilityError, OMEGA, coverability};
pub use dot::{graph_to_dot, net_to_dot};
pub use explore::{ExploreError, Options, Progress, StateSpace, explore};
pub use net::{
    Arc, ArcKind, Marking, MarkingDisplay, Net, NetError, Place, PlaceId, Transition, TransitionId,
};
pub use pnml::{PnmlError, from_pnml, to_pnml};
