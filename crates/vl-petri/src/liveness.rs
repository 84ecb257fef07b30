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

impl Liveness {
    /// The level of a transition that fires inside every terminal strongly
    /// connected component, on some cycle, or at all.
    pub(crate) fn of(in_every_terminal: bool, on_a_cycle: bool, fires: bool) -> Liveness {
        if in_every_terminal {
            Liveness::L4
        } else if on_a_cycle {
            Liveness::L3
        } else if fires {
            Liveness::L1
        } else {
            Liveness::L0
        }
    }
}
