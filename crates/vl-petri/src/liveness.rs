//! How live a transition is: what both the stored reachability graph
//! (`analysis`) and the on-the-fly reading (`onthefly`) report.

use serde::Serialize;

/// Liveness level of a transition (Murata 1989), for a finite reachability graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub enum Liveness {
    /// Dead: never fires.
    L0,
    /// Fires in some firing sequence.
    L1,
    /// Fires infinitely often in some sequence (on a finite graph the same as L2).
    L3,
    /// Live: can fire again from every reachable marking.
    L4,
}
