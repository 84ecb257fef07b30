//! Behavioural properties read off the reachability graph, and structural
//! ones read off the incidence matrix.
//!
//! In the thesis these are event-based properties of a lab: bounded = no
//! accumulation of signals; live and deadlock-free = the experiment can
//! always proceed; reversible = the lab can always return to idle.

use serde::Serialize;

use crate::explore::{Bounds, ExploreError, Options, StateSpace, explore_until_dead};
use crate::linalg::rank;
use crate::liveness::Liveness;
use crate::net::Net;

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
    /// Bytes each marking took, packed.
    pub bytes_per_marking: usize,
}

/// Analyses `net` whose reachability graph is `space`.
pub fn analyze(net: &Net, space: &StateSpace) -> Analysis {
    let dead_state = (0..space.states()).find(|&s| space.successors(s).next().is_none());
    let Components { count, liveness } = components(space, net.transitions.len());
    assemble(
        net,
        Read {
            states: space.states(),
            edges: space.edges(),
            bounds: space.bounds(),
            deadlock_trace: dead_state.map(|d| firing_sequence(space, d)),
            components: count,
            liveness,
            bytes_per_marking: space.bytes_per_marking(),
        },
    )
}

/// Analyses `net` without keeping its reachability graph: Tarjan's
/// algorithm runs inside a depth-first search (see `onthefly`), so memory
/// goes to the markings alone. When a marking is dead, a breadth-first
/// search then finds a shortest way to one, keeping the graph only that far.
pub fn analyze_net(net: &Net, mut options: Options) -> Result<Analysis, ExploreError> {
    let max_states = options.max_states;
    let reading = crate::onthefly::read(net, &mut options).map_err(|stop| match stop {
        crate::onthefly::Stop::Limit => ExploreError::TooManyStates {
            limit: max_states.min(crate::onthefly::MOST_STATES),
        },
        _ => ExploreError::TokenOverflow,
    })?;
    let deadlock_trace = if reading.dead {
        let (space, dead) = explore_until_dead(net, options)?;
        Some(firing_sequence(
            &space,
            dead.expect("the search met a dead marking"),
        ))
    } else {
        None
    };
    Ok(assemble(
        net,
        Read {
            states: reading.states,
            edges: reading.edges,
            bounds: &reading.bounds,
            deadlock_trace,
            components: reading.components,
            liveness: reading.liveness,
            bytes_per_marking: reading.bytes_per_marking,
        },
    ))
}

/// What a search read off the state space.
struct Read<'a> {
    states: usize,
    edges: usize,
    bounds: &'a Bounds,
    /// Transitions of a shortest firing sequence to a dead marking.
    deadlock_trace: Option<Vec<usize>>,
    components: usize,
    liveness: Vec<Liveness>,
    bytes_per_marking: usize,
}

/// The analysis of `net` from what a search read and its incidence matrix.
fn assemble(net: &Net, read: Read) -> Analysis {
    let transitions = net.transitions.len();
    let bounds = read.bounds;
    let max_tokens_in_place = bounds.per_place();
    let liveness = read.liveness;
    let r = incidence_rank(net);
    Analysis {
        places: net.places.len(),
        transitions,
        states: read.states,
        edges: read.edges,
        bounded: true,
        max_tokens_in_place,
        max_tokens_per_marking: bounds.per_marking,
        place_bounds: bounds.places.clone(),
        safe: max_tokens_in_place <= 1,
        deadlock: read.deadlock_trace.is_some(),
        deadlock_trace: read.deadlock_trace.map(|trace| {
            trace
                .into_iter()
                .map(|t| net.transitions[t].id.clone())
                .collect()
        }),
        quasi_live: liveness.iter().all(|&l| l >= Liveness::L1),
        live: liveness.iter().all(|&l| l == Liveness::L4),
        liveness,
        reversible: read.components == 1,
        p_flow_basis_dim: net.places.len() - r,
        t_flow_basis_dim: transitions - r,
        bytes_per_marking: read.bytes_per_marking,
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

/// The nearest state from which the initial one can never be reached
/// again (a dead end, or a corner of the graph with no way back), if any:
/// what makes a net not reversible, to show with [`firing_sequence`].
pub fn no_way_back(space: &StateSpace) -> Option<usize> {
    let states = space.states();
    let mut into: Vec<Vec<usize>> = vec![Vec::new(); states];
    for s in 0..states {
        for (_, to) in space.successors(s) {
            into[to].push(s);
        }
    }
    let mut back = vec![false; states];
    let mut stack = vec![0];
    back[0] = true;
    while let Some(s) = stack.pop() {
        for &from in &into[s] {
            if !back[from] {
                back[from] = true;
                stack.push(from);
            }
        }
    }
    // States are numbered breadth-first: the lowest is the nearest.
    back.iter().position(|&b| !b)
}

/// What the strongly connected components of the reachability graph say:
/// how many there are, and each transition's liveness level.
struct Components {
    count: usize,
    liveness: Vec<Liveness>,
}

/// Tarjan's algorithm, iterative so millions of states do not overflow the
/// stack. Each edge is told apart as it is followed: into a state still on
/// the stack (once its own search is over), it stays inside the component
/// being built; into a finished component, it leaves. So when a component
/// is popped, it is terminal exactly when none of its states has an edge
/// leaving, and only then are its states' transitions read again, to count
/// it for each transition firing inside it.
///
/// A transition is L4 if it fires inside every terminal component (so it
/// can fire again from everywhere), L3 if inside some component (a cycle),
/// L1 if it fires at all.
fn components(space: &StateSpace, transitions: usize) -> Components {
    const UNSEEN: u32 = u32::MAX;
    // Per state: on the stack; has an edge leaving its component.
    const ON_STACK: u8 = 1;
    const EXITS: u8 = 2;
    let n = space.states();
    let mut index = vec![UNSEEN; n];
    let mut low = vec![0u32; n];
    let mut flags = vec![0u8; n];
    let mut stack: Vec<u32> = Vec::new();
    // (state, position in its successor list)
    let mut calls: Vec<(u32, u32)> = Vec::new();
    let mut next_index = 0u32;
    let mut count = 0u32;
    let mut fires = vec![false; transitions];
    let mut cycles = vec![false; transitions];
    let mut terminals = 0usize;
    let mut in_terminals = vec![0usize; transitions];
    // The last terminal component each transition was counted for.
    let mut seen_in = vec![UNSEEN; transitions];
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
                flags[v] |= ON_STACK;
            }
            let k = *pos as usize;
            let successor = space.targets(v).get(k).map(|&w| w as usize);
            *pos += 1;
            match successor {
                Some(w) if index[w] == UNSEEN => calls.push((w as u32, 0)),
                Some(w) => {
                    let t = space.label(v, k);
                    fires[t] = true;
                    if flags[w] & ON_STACK != 0 {
                        low[v] = low[v].min(index[w]);
                        cycles[t] = true;
                    } else {
                        flags[v] |= EXITS;
                    }
                }
                None => {
                    calls.pop();
                    if let Some(&(parent, _)) = calls.last() {
                        let parent = parent as usize;
                        low[parent] = low[parent].min(low[v]);
                    }
                    if low[v] == index[v] {
                        let from = stack
                            .iter()
                            .rposition(|&w| w as usize == v)
                            .expect("v is on the stack");
                        let members = &stack[from..];
                        if members.iter().all(|&w| flags[w as usize] & EXITS == 0) {
                            terminals += 1;
                            fired_inside(space, members, count, &mut seen_in, &mut in_terminals);
                        }
                        for &w in members {
                            flags[w as usize] &= !ON_STACK;
                        }
                        stack.truncate(from);
                        count += 1;
                    }
                    // The tree edge from the parent: inside its component
                    // if v is still on the stack, leaving it if not.
                    if let Some(&(parent, next)) = calls.last() {
                        let (parent, k) = (parent as usize, next as usize - 1);
                        let t = space.label(parent, k);
                        fires[t] = true;
                        if flags[v] & ON_STACK != 0 {
                            cycles[t] = true;
                        } else {
                            flags[parent] |= EXITS;
                        }
                    }
                }
            }
        }
    }
    let liveness = (0..transitions)
        .map(|t| {
            Liveness::of(
                in_terminals[t] == terminals && terminals > 0,
                cycles[t],
                fires[t],
            )
        })
        .collect();
    Components {
        count: count as usize,
        liveness,
    }
}

/// Counts, once for the terminal component `count` of `members`, each
/// transition that fires inside it.
fn fired_inside(
    space: &StateSpace,
    members: &[u32],
    count: u32,
    seen_in: &mut [u32],
    in_terminals: &mut [usize],
) {
    for &w in members {
        for (t, _) in space.successors(w as usize) {
            if seen_in[t] != count {
                seen_in[t] = count;
                in_terminals[t] += 1;
            }
        }
    }
}

/// The rank of the net's incidence matrix: |P| − rank is the dimension of
/// the P-flow (place invariant) basis, |T| − rank that of the T-flow basis.
pub fn incidence_rank(net: &Net) -> usize {
    rank(&net.incidence())
}
