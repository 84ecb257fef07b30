//! Behavioural properties read off the reachability graph, and structural
//! ones read off the incidence matrix.
//!
//! In the thesis these are event-based properties of a lab: bounded = no
//! accumulation of signals; live and deadlock-free = the experiment can
//! always proceed; reversible = the lab can always return to idle.

use serde::Serialize;

use crate::explore::StateSpace;
use crate::linalg::rank;
use crate::net::Net;

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

/// What the state space and the incidence matrix say about a net.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    pub places: usize,
    pub transitions: usize,
    pub states: usize,
    pub edges: usize,
    pub bounded: bool,
    /// The most tokens any place holds in any reachable marking.
    pub max_tokens_in_place: u32,
    /// The most tokens in any reachable marking.
    pub max_tokens_per_marking: u64,
    /// The bound of each place.
    pub place_bounds: Vec<u32>,
    pub safe: bool,
    pub deadlock: bool,
    /// A shortest firing sequence (transition ids) to a dead marking.
    pub deadlock_trace: Option<Vec<String>>,
    pub quasi_live: bool,
    pub liveness: Vec<Liveness>,
    /// Every transition is L4-live.
    pub live: bool,
    /// The initial marking is reachable from every reachable marking.
    pub reversible: bool,
    pub p_flow_basis_dim: usize,
    pub t_flow_basis_dim: usize,
}

/// Analyses `net` whose reachability graph is `space`.
pub fn analyze(net: &Net, space: &StateSpace) -> Analysis {
    let n = space.states();
    let transitions = net.transitions.len();

    let mut place_bounds = vec![0u32; net.places.len()];
    let mut max_tokens_per_marking = 0u64;
    space.for_each_marking(|m| {
        let mut sum = 0u64;
        for (bound, &v) in place_bounds.iter_mut().zip(m) {
            *bound = (*bound).max(v);
            sum += u64::from(v);
        }
        max_tokens_per_marking = max_tokens_per_marking.max(sum);
    });
    let max_tokens_in_place = place_bounds.iter().copied().max().unwrap_or(0);

    let dead_state = (0..n).find(|&s| space.successors(s).next().is_none());
    let deadlock_trace = dead_state.map(|d| {
        firing_sequence(space, d)
            .into_iter()
            .map(|t| net.transitions[t].id.clone())
            .collect()
    });

    let components = strongly_connected(space);
    let liveness = liveness(space, &components, transitions);
    let r = incidence_rank(net);
    Analysis {
        places: net.places.len(),
        transitions,
        states: n,
        edges: space.edges(),
        bounded: true,
        max_tokens_in_place,
        max_tokens_per_marking,
        place_bounds,
        safe: max_tokens_in_place <= 1,
        deadlock: dead_state.is_some(),
        deadlock_trace,
        quasi_live: liveness.iter().all(|&l| l >= Liveness::L1),
        live: liveness.iter().all(|&l| l == Liveness::L4),
        liveness,
        reversible: components.count == 1,
        p_flow_basis_dim: net.places.len() - r,
        t_flow_basis_dim: transitions - r,
    }
}

/// The transitions of a shortest firing sequence from the initial state to
/// `target`. States are numbered in breadth-first order, so the first state
/// (lowest number) with an edge into a state is its BFS parent.
pub fn firing_sequence(space: &StateSpace, target: usize) -> Vec<usize> {
    const NONE: u32 = u32::MAX;
    let mut parent = vec![(NONE, NONE); target + 1];
    for s in 0..=target {
        for (t, to) in space.successors(s) {
            if to <= target && to != 0 && parent[to].0 == NONE {
                parent[to] = (s as u32, t as u32);
            }
        }
    }
    let mut path = Vec::new();
    let mut at = target;
    while at != 0 {
        let (from, t) = parent[at];
        path.push(t as usize);
        at = from as usize;
    }
    path.reverse();
    path
}

/// Strongly connected components of the reachability graph.
pub struct Components {
    /// Component of each state.
    pub of: Vec<u32>,
    pub count: usize,
}

/// Tarjan's algorithm, iterative so millions of states do not overflow the stack.
pub fn strongly_connected(space: &StateSpace) -> Components {
    const UNSEEN: u32 = u32::MAX;
    let n = space.states();
    let mut index = vec![UNSEEN; n];
    let mut low = vec![0u32; n];
    let mut on_stack = vec![false; n];
    let mut of = vec![UNSEEN; n];
    let mut stack: Vec<u32> = Vec::new();
    // (state, position in its successor list)
    let mut calls: Vec<(u32, u32)> = Vec::new();
    let mut next_index = 0u32;
    let mut count = 0usize;
    for root in 0..n {
        if index[root] != UNSEEN {
            continue;
        }
        calls.push((root as u32, 0));
        while let Some(&mut (v, ref mut pos)) = calls.last_mut() {
            let v = v as usize;
            if *pos == 0 && index[v] == UNSEEN {
                index[v] = next_index;
                low[v] = next_index;
                next_index += 1;
                stack.push(v as u32);
                on_stack[v] = true;
            }
            let successor = space.targets(v).get(*pos as usize).map(|&w| w as usize);
            *pos += 1;
            match successor {
                Some(w) if index[w] == UNSEEN => calls.push((w as u32, 0)),
                Some(w) => {
                    if on_stack[w] {
                        low[v] = low[v].min(index[w]);
                    }
                }
                None => {
                    calls.pop();
                    if let Some(&(parent, _)) = calls.last() {
                        let parent = parent as usize;
                        low[parent] = low[parent].min(low[v]);
                    }
                    if low[v] == index[v] {
                        loop {
                            let w = stack.pop().expect("v is on the stack") as usize;
                            on_stack[w] = false;
                            of[w] = count as u32;
                            if w == v {
                                break;
                            }
                        }
                        count += 1;
                    }
                }
            }
        }
    }
    Components { of, count }
}

/// Liveness level of each transition: L4 if it labels an edge inside every
/// terminal component (so it can fire again from everywhere), L3 if it labels
/// an edge inside some component (a cycle), L1 if it fires at all.
fn liveness(space: &StateSpace, components: &Components, transitions: usize) -> Vec<Liveness> {
    let n = space.states();
    let mut fires = vec![false; transitions];
    let mut cycles = vec![false; transitions];
    let mut terminal = vec![true; components.count];
    for s in 0..n {
        let c = components.of[s];
        for (t, to) in space.successors(s) {
            fires[t] = true;
            if components.of[to] == c {
                cycles[t] = true;
            } else {
                terminal[c as usize] = false;
            }
        }
    }
    // Count, per transition, the terminal components it fires inside.
    let terminals = terminal.iter().filter(|&&t| t).count();
    let mut seen_in = vec![u32::MAX; transitions];
    let mut in_terminals = vec![0usize; transitions];
    let mut by_component: Vec<Vec<u32>> = vec![Vec::new(); components.count];
    for s in 0..n {
        let c = components.of[s] as usize;
        if terminal[c] {
            by_component[c].push(s as u32);
        }
    }
    for (c, states) in by_component.iter().enumerate() {
        for &s in states {
            for (t, _) in space.successors(s as usize) {
                if seen_in[t] != c as u32 {
                    seen_in[t] = c as u32;
                    in_terminals[t] += 1;
                }
            }
        }
    }
    (0..transitions)
        .map(|t| {
            if in_terminals[t] == terminals && terminals > 0 {
                Liveness::L4
            } else if cycles[t] {
                Liveness::L3
            } else if fires[t] {
                Liveness::L1
            } else {
                Liveness::L0
            }
        })
        .collect()
}

/// The rank of the net's incidence matrix: |P| − rank is the dimension of
/// the P-flow (place invariant) basis, |T| − rank that of the T-flow basis.
pub fn incidence_rank(net: &Net) -> usize {
    rank(&net.incidence())
}
