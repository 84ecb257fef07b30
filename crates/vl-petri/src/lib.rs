//! Petri nets for `vl`: the formalism the thesis designs every lab in.
//!
//! [`net`] holds the model and its firing rule (the session supervisor in
//! `vl-core` runs it live), [`pnml`] moves nets in and out, [`explore`]
//! builds the reachability graph and [`analysis`] reads properties off it.

pub mod analysis;
pub mod explore;
mod linalg;
pub mod net;
pub mod pnml;

pub use analysis::{Analysis, Liveness, analyze};
pub use explore::{ExploreError, Options, Progress, StateSpace, explore};
pub use net::{
    Arc, ArcKind, Marking, MarkingDisplay, Net, NetError, Place, PlaceId, Transition, TransitionId,
};
pub use pnml::{PnmlError, from_pnml, to_pnml};
