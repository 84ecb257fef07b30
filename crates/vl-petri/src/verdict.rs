//! The whole analysis of a net, in the order that answers soonest: a net
//! a P-invariant weighs entirely (conservative) is bounded; otherwise a
//! small Karp–Miller tree settles boundedness when it can do so cheaply,
//! since an unbounded net would explore until the state limit; only then
//! is the reachability graph explored and read.

use crate::{
    Analysis, ExploreError, Net, Options, analyze_net, coverability, is_conservative, p_invariants,
    p_rows_within,
};

/// Rows the Farkas algorithm may hold while deciding conservativeness, and
/// the memory it may take: less than exploring a large net takes, so the
/// verdict never sets the peak.
const CONSERVATIVE_ROWS: usize = 20_000;
const CONSERVATIVE_BYTES: usize = 32 << 20;

/// Nodes the boundedness pre-check may build before leaving the question
/// to full exploration: enough for a small unbounded net to be named at
/// once, little enough (a fraction of a second) not to weigh on a large
/// bounded one. A larger net stops at the state limit, which says where to
/// look.
const QUICK_COVERABILITY_NODES: usize = 10_000;

/// What the analysis found.
#[derive(Debug, Clone, PartialEq)]
pub struct NetVerdict {
    /// Whether a positive weighting of all places is invariant, if the
    /// minimal P-invariants could be listed within their limits.
    pub conservative: Option<bool>,
    /// What the reachability graph says; none for an unbounded net.
    pub analysis: Option<Analysis>,
    /// The places that grow without bound, for an unbounded net.
    pub unbounded: Vec<usize>,
}

/// Whether a positive weighting of all places is invariant, if the minimal
/// P-invariants can be listed within their limits.
fn conservative(net: &Net) -> Option<bool> {
    let rows = CONSERVATIVE_ROWS.min(p_rows_within(net, CONSERVATIVE_BYTES));
    let invariants = p_invariants(net, rows).ok()?;
    Some(is_conservative(net.places.len(), &invariants))
}

/// Analyses `net`: boundedness settled first when it is cheap, then the
/// reachability graph explored within `options`.
pub fn verdict(net: &Net, options: Options) -> Result<NetVerdict, ExploreError> {
    let conservative = conservative(net);
    let quick = match conservative {
        Some(true) => None,
        _ => coverability(net, QUICK_COVERABILITY_NODES).ok(),
    };
    if let Some(c) = quick.filter(|c| !c.bounded()) {
        return Ok(NetVerdict {
            conservative,
            analysis: None,
            unbounded: c.unbounded,
        });
    }
    Ok(NetVerdict {
        conservative,
        analysis: Some(analyze_net(net, options)?),
        unbounded: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unbounded_net_is_named_without_exploring_it() {
        let mut net = Net::new("pump");
        net.add_place("tank", 0).unwrap();
        net.add_transition_with("fill", None, &[], &[("tank", 1)])
            .unwrap();
        let options = Options {
            max_states: 10,
            ..Options::default()
        };
        let v = verdict(&net, options).expect("no exploration to stop");
        assert_eq!(v.unbounded, vec![0]);
        assert!(v.analysis.is_none());
        assert_eq!(v.conservative, Some(false));
    }

    #[test]
    fn a_conservative_net_is_explored() {
        let mut net = Net::new("token ring");
        net.add_place("a", 1).unwrap();
        net.add_place("b", 0).unwrap();
        net.add_transition_with("ab", None, &[("a", 1)], &[("b", 1)])
            .unwrap();
        net.add_transition_with("ba", None, &[("b", 1)], &[("a", 1)])
            .unwrap();
        let v = verdict(&net, Options::default()).unwrap();
        assert_eq!(v.conservative, Some(true));
        let a = v.analysis.expect("explored");
        assert_eq!((a.states, a.live, a.bounded), (2, true, true));
    }
}
