//! Karp–Miller coverability: a finite over-approximation of an unbounded
//! net's reachable markings, with ω standing for "as many as you like".
//!
//! Built as a graph (identical ω-markings merged) from the initial marking:
//! when a new marking strictly covers one on its path from the root, the
//! places that grew become ω. It decides boundedness — a place is unbounded
//! exactly when some node gives it ω — and its maximal nodes cover every
//! reachable marking. With inhibitor arcs or capacities the firing rule is
//! not monotone and the construction is unsound, so such nets are refused.

use std::collections::HashMap;

use thiserror::Error;

use crate::net::Net;

/// "Unboundedly many tokens".
pub const OMEGA: u32 = u32::MAX;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum CoverabilityError {
    #[error(
        "coverability is unsound with inhibitor arcs (transition '{0}' has one); \
         explore the reachability graph instead"
    )]
    Inhibitor(String),
    #[error(
        "coverability is unsound with place capacities (place '{0}' has one); \
         model the capacity with a complementary place"
    )]
    Capacity(String),
    #[error("the coverability graph grew past {0} nodes")]
    TooLarge(usize),
}

/// The coverability graph's nodes and what they say.
#[derive(Debug, Clone)]
pub struct Coverability {
    /// ω-markings, the root first.
    pub nodes: Vec<Vec<u32>>,
    /// (from, transition, to) for every firing between nodes.
    pub edges: Vec<(usize, usize, usize)>,
    /// Places that are ω somewhere.
    pub unbounded: Vec<usize>,
}

impl Coverability {
    pub fn bounded(&self) -> bool {
        self.unbounded.is_empty()
    }

    /// The nodes no other node covers, in node order (duplicates removed).
    pub fn maximal(&self) -> Vec<&[u32]> {
        let covers = |a: &[u32], b: &[u32]| a.iter().zip(b).all(|(x, y)| x >= y);
        let mut maximal: Vec<&[u32]> = Vec::new();
        for m in &self.nodes {
            if maximal.iter().any(|k| covers(k, m)) {
                continue;
            }
            maximal.retain(|k| !covers(m, k));
            maximal.push(m);
        }
        maximal
    }
}

/// Builds the Karp–Miller coverability graph of `net`, up to `max_nodes` nodes.
pub fn coverability(net: &Net, max_nodes: usize) -> Result<Coverability, CoverabilityError> {
    if let Some(t) = net.transitions.iter().find(|t| !t.inhibit.is_empty()) {
        return Err(CoverabilityError::Inhibitor(t.id.clone()));
    }
    if let Some(p) = net.places.iter().find(|p| p.capacity.is_some()) {
        return Err(CoverabilityError::Capacity(p.id.clone()));
    }
    let root = net.initial_marking().0;
    let mut nodes = vec![root.clone()];
    let mut parent: Vec<Option<usize>> = vec![None];
    let mut index: HashMap<Vec<u32>, usize> = HashMap::from([(root, 0)]);
    let mut edges = Vec::new();
    let mut next = 0;
    while next < nodes.len() {
        let m = nodes[next].clone();
        for (t, tr) in net.transitions.iter().enumerate() {
            if !tr.pre.iter().all(|a| m[a.place.0] >= a.weight) {
                continue;
            }
            let mut succ = m.clone();
            for a in &tr.pre {
                if succ[a.place.0] != OMEGA {
                    succ[a.place.0] -= a.weight;
                }
            }
            for a in &tr.post {
                let v = &mut succ[a.place.0];
                if *v != OMEGA {
                    *v = v.saturating_add(a.weight).min(OMEGA - 1);
                }
            }
            accelerate(&mut succ, next, &nodes, &parent);
            let to = match index.get(&succ) {
                Some(&to) => to,
                None => {
                    if nodes.len() >= max_nodes {
                        return Err(CoverabilityError::TooLarge(max_nodes));
                    }
                    nodes.push(succ.clone());
                    parent.push(Some(next));
                    index.insert(succ, nodes.len() - 1);
                    nodes.len() - 1
                }
            };
            edges.push((next, t, to));
        }
        next += 1;
    }
    let unbounded = (0..net.places.len())
        .filter(|&p| nodes.iter().any(|m| m[p] == OMEGA))
        .collect();
    Ok(Coverability {
        nodes,
        edges,
        unbounded,
    })
}

/// Sets to ω every place that grew since an ancestor `m` strictly covers.
fn accelerate(m: &mut [u32], from: usize, nodes: &[Vec<u32>], parent: &[Option<usize>]) {
    let mut at = Some(from);
    while let Some(a) = at {
        let ancestor = &nodes[a];
        if ancestor.iter().zip(m.iter()).all(|(x, y)| x <= y) && ancestor[..] != m[..] {
            for (v, &x) in m.iter_mut().zip(ancestor) {
                if *v > x {
                    *v = OMEGA;
                }
            }
        }
        at = parent[a];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_producer_makes_its_buffer_unbounded() {
        let mut net = Net::new("producer");
        net.add_place("ready", 1).unwrap();
        net.add_place("buffer", 0).unwrap();
        net.add_transition_with(
            "produce",
            None,
            &[("ready", 1)],
            &[("ready", 1), ("buffer", 1)],
        )
        .unwrap();
        let c = coverability(&net, 100).unwrap();
        assert!(!c.bounded());
        assert_eq!(c.unbounded, vec![1]);
        assert_eq!(c.maximal(), vec![&[1, OMEGA][..]]);
    }

    #[test]
    fn inhibitors_are_refused() {
        let mut net = Net::new("n");
        net.add_place("p", 0).unwrap();
        let t = net.add_transition("t", None).unwrap();
        net.add_arc(crate::net::ArcKind::Inhibitor, "p", t, 1)
            .unwrap();
        assert_eq!(
            coverability(&net, 10).unwrap_err(),
            CoverabilityError::Inhibitor("t".into())
        );
    }
}
