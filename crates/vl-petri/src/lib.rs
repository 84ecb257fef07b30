//! Petri nets for `vl`: the formalism the thesis designs every lab in.
//!
//! Today this crate holds the net model and its firing rule, which the
//! session supervisor in `vl-core` runs live. Analysis (reachability,
//! coverability, invariants), composition, controller synthesis and PNML
//! interchange grow here.

mod net;

pub use net::{Arc, Marking, MarkingDisplay, Net, NetError, PlaceId, Transition, TransitionId};
