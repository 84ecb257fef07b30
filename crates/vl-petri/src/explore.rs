//! Explicit state-space exploration: the reachability graph.
//!
//! States are numbered in breadth-first discovery order, so the store of
//! markings is also the BFS queue and successors are appended to a
//! compressed adjacency list (CSR) as each state is expanded — no separate
//! queue, no per-edge allocation. Markings are bit-packed: a place whose
//! bound the P-invariants prove gets just the bits that bound needs (a safe
//! place one bit); any other place starts with the bits its initial count
//! needs and, the first time a count outgrows them, the store is repacked
//! with that place twice as wide and exploration goes on where it was. A
//! successor is built by copying its parent's packed bytes and rewriting only
//! the places the transition changes.

use std::hash::Hasher;
use std::time::{Duration, Instant};

use hashbrown::HashTable;
use rustc_hash::FxHasher;
use thiserror::Error;

use crate::layout::{
    Candidates, Compiled, Firing, Layout, PAD, compile, fire, initial_layout, repack,
};
use crate::net::{Marking, Net};

/// Why exploration stopped without a complete graph.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum ExploreError {
    #[error("stopped at the limit of {limit} states before the state space was complete")]
    TooManyStates { limit: usize },
    #[error("stopped at its deadline before the state space was complete")]
    OutOfTime,
    #[error(
        "a place would hold more than {} tokens: the net is unbounded or nearly so",
        u32::MAX
    )]
    TokenOverflow,
}

/// Progress of a running exploration.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub states: usize,
    pub edges: usize,
    pub elapsed: Duration,
}

/// Limits and reporting for [`explore`].
pub struct Options<'a> {
    pub max_states: usize,
    /// Called every few hundred thousand states.
    pub progress: Option<&'a mut dyn FnMut(Progress)>,
    /// Stop when still exploring at this time (looked at every
    /// [`DEADLINE_EVERY`] states).
    pub deadline: Option<Instant>,
}

impl Default for Options<'_> {
    fn default() -> Self {
        Options {
            max_states: usize::MAX,
            progress: None,
            deadline: None,
        }
    }
}

/// The reachability graph: every reachable marking and every firing between them.
#[derive(Debug, Clone)]
pub struct StateSpace {
    layout: Layout,
    /// Packed markings, `layout.stride` bytes each, in state order.
    store: Vec<u8>,
    /// `edges_from[s]..edges_from[s + 1]` index the successors of state s.
    edges_from: Vec<u64>,
    /// Target state of each edge.
    edge_to: Vec<u32>,
    /// Transition fired on each edge.
    edge_by: Labels,
    bounds: Bounds,
}

/// The transition of each edge, in as few bytes as the net's transition
/// count needs: most nets have under 256, and edges outnumber states
/// several times, so this is a good part of the graph's memory.
#[derive(Debug, Clone)]
pub(crate) enum Labels {
    One(Vec<u8>),
    Two(Vec<u16>),
    Four(Vec<u32>),
}

impl Labels {
    pub(crate) fn for_transitions(n: usize) -> Labels {
        match Labels::bytes(n) {
            1 => Labels::One(Vec::new()),
            2 => Labels::Two(Vec::new()),
            _ => Labels::Four(Vec::new()),
        }
    }

    /// Bytes a label of one of `n` transitions takes.
    pub(crate) fn bytes(n: usize) -> usize {
        if n <= 1 << 8 {
            1
        } else if n <= 1 << 16 {
            2
        } else {
            4
        }
    }

    /// Appends `t`, which is below the transition count given.
    pub(crate) fn push(&mut self, t: u32) {
        match self {
            Labels::One(v) => v.push(t as u8),
            Labels::Two(v) => v.push(t as u16),
            Labels::Four(v) => v.push(t),
        }
    }

    pub(crate) fn get(&self, e: usize) -> u32 {
        match self {
            Labels::One(v) => u32::from(v[e]),
            Labels::Two(v) => u32::from(v[e]),
            Labels::Four(v) => v[e],
        }
    }

    pub(crate) fn len(&self) -> usize {
        match self {
            Labels::One(v) => v.len(),
            Labels::Two(v) => v.len(),
            Labels::Four(v) => v.len(),
        }
    }

    pub(crate) fn truncate(&mut self, n: usize) {
        match self {
            Labels::One(v) => v.truncate(n),
            Labels::Two(v) => v.truncate(n),
            Labels::Four(v) => v.truncate(n),
        }
    }
}

/// How often the deadline is looked at, in expanded states.
pub(crate) const DEADLINE_EVERY: usize = 1 << 12;

/// How often progress is reported, in expanded states.
pub(crate) const PROGRESS_EVERY: usize = 1 << 18;

/// Explores every marking reachable from the initial one, keeping the
/// graph's edges (liveness and reversibility are read off them).
pub fn explore(net: &Net, mut options: Options) -> Result<StateSpace, ExploreError> {
    let found = start(net, &mut options, Keep::Graph)?;
    Ok(found.into_space())
}

/// The reachability graph up to the first dead marking breadth-first, and
/// that marking's state; the whole graph and None when no marking is dead.
pub(crate) fn explore_until_dead(
    net: &Net,
    mut options: Options,
) -> Result<(StateSpace, Option<usize>), ExploreError> {
    let found = start(net, &mut options, Keep::GraphUntilDead)?;
    let dead = found.dead;
    Ok((found.into_space(), dead))
}

impl Found {
    fn into_space(self) -> StateSpace {
        let Graph {
            edges_from,
            edge_to,
            edge_by,
        } = self.graph;
        StateSpace {
            layout: self.layout,
            store: self.store,
            edges_from,
            edge_to,
            edge_by,
            bounds: self.bounds,
        }
    }
}

/// What exploration alone says, as `verifypn -e` reports it: the state
/// space's size and the bounds of its places.
#[derive(Debug, Clone, PartialEq)]
pub struct StateCount {
    pub states: usize,
    /// Firings between markings: every enabled transition of every state.
    pub edges: usize,
    pub bounds: Bounds,
    pub bytes_per_marking: usize,
}

/// The most tokens each place, and any marking, holds: taken as each state
/// is expanded, so no pass over the store is needed afterwards.
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    /// Per place.
    pub places: Vec<u32>,
    /// The most tokens in any one marking.
    pub per_marking: u64,
}

impl Bounds {
    pub(crate) fn new(places: usize) -> Bounds {
        Bounds {
            places: vec![0; places],
            per_marking: 0,
        }
    }

    pub(crate) fn take(&mut self, m: &[u32]) {
        let mut sum = 0u64;
        for (bound, &v) in self.places.iter_mut().zip(m) {
            *bound = (*bound).max(v);
            sum += u64::from(v);
        }
        self.per_marking = self.per_marking.max(sum);
    }

    /// Takes in what `other` found too.
    pub(crate) fn join(&mut self, other: &Bounds) {
        for (a, &b) in self.places.iter_mut().zip(&other.places) {
            *a = (*a).max(b);
        }
        self.per_marking = self.per_marking.max(other.per_marking);
    }

    /// The most tokens in any one place.
    pub fn per_place(&self) -> u32 {
        self.places.iter().copied().max().unwrap_or(0)
    }
}

/// Lays out the markings and runs the search.
fn start(net: &Net, options: &mut Options, keep: Keep) -> Result<Found, ExploreError> {
    let compiled = compile(net);
    let initial = net.initial_marking();
    run(initial_layout(net), &compiled, &initial, options, keep).map_err(|stop| match stop {
        Stop::Overflow => ExploreError::TokenOverflow,
        Stop::Limit => ExploreError::TooManyStates {
            limit: options.max_states,
        },
        Stop::OutOfTime => ExploreError::OutOfTime,
    })
}

/// The index of the first `states` markings of `store`, `stride` bytes each.
fn index(store: &[u8], stride: usize, states: usize) -> HashTable<u32> {
    let mut table = HashTable::with_capacity(states);
    for id in 0..states {
        let s = id * stride;
        table.insert_unique(hash_of(&store[s..s + stride]), id as u32, |&id| {
            let s = id as usize * stride;
            hash_of(&store[s..s + stride])
        });
    }
    table
}

/// The number of `marking` in `store`, which takes it as the next state
/// if it is new (no more than `max_states` of them).
#[inline]
fn intern(
    table: &mut HashTable<u32>,
    store: &mut Vec<u8>,
    stride: usize,
    marking: &[u8],
    states: &mut usize,
    max_states: usize,
) -> Result<u32, Stop> {
    let hash = hash_of(marking);
    let found = table
        .find(hash, |&id| {
            let s = id as usize * stride;
            store[s..s + stride] == *marking
        })
        .copied();
    if let Some(id) = found {
        return Ok(id);
    }
    if *states >= max_states {
        return Err(Stop::Limit);
    }
    let id = *states as u32;
    store.extend_from_slice(marking);
    *states += 1;
    table.insert_unique(hash, id, |&id| {
        let s = id as usize * stride;
        hash_of(&store[s..s + stride])
    });
    Ok(id)
}

/// The reachability graph's edges, in compressed adjacency form.
struct Graph {
    edges_from: Vec<u64>,
    edge_to: Vec<u32>,
    edge_by: Labels,
}

/// What a search found: the markings and the edges between them.
struct Found {
    layout: Layout,
    store: Vec<u8>,
    graph: Graph,
    bounds: Bounds,
    /// The first dead state, when the search stopped there.
    dead: Option<usize>,
}

/// How far a search goes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Keep {
    Graph,
    /// The graph until the first dead state, where it stops.
    GraphUntilDead,
}

enum Stop {
    Overflow,
    Limit,
    OutOfTime,
}

fn hash_of(m: &[u8]) -> u64 {
    let mut h = FxHasher::default();
    h.write(m);
    h.finish()
}

fn run(
    mut layout: Layout,
    compiled: &[Compiled],
    initial: &Marking,
    options: &mut Options,
    keep: Keep,
) -> Result<Found, Stop> {
    let mut dead = None;
    let mut stride = layout.stride;
    let started = Instant::now();
    let mut next = vec![0u8; stride + PAD];
    layout.pack(&initial.0, &mut next);
    let mut store: Vec<u8> = next[..stride].to_vec();
    let mut table: HashTable<u32> = HashTable::new();
    let mut states = 1usize;
    table.insert_unique(hash_of(&store[..stride]), 0, |_| 0);
    let mut edges_from: Vec<u64> = vec![0];
    let mut edge_to: Vec<u32> = Vec::new();
    let mut edge_by = Labels::for_transitions(compiled.len());
    // Firings counted so far.
    let mut edges = 0usize;
    let mut bounds = Bounds::new(layout.places());
    let mut current = vec![0u32; layout.places()];
    let mut packed = vec![0u8; stride + PAD];
    let mut expanded = 0usize;
    let candidates = Candidates::new(compiled, layout.places());
    let mut enabled: Vec<u32> = Vec::with_capacity(compiled.len());
    // Places that have been seen full: the next overflow widens them too.
    let mut at_limit = vec![false; layout.places()];
    'states: while expanded < states {
        let at = expanded * stride;
        packed[..stride].copy_from_slice(&store[at..at + stride]);
        layout.unpack(&packed, &mut current);
        bounds.take(&current);
        enabled.clear();
        candidates.enabled(compiled, &current, &mut enabled);
        // Where this state's firings start, should it be expanded again.
        let edges_before = edges;
        for &t in &enabled {
            next.copy_from_slice(&packed);
            match fire(
                &layout,
                &compiled[t as usize],
                |p| current[p],
                &mut next,
                &mut at_limit,
            ) {
                Firing::Next => {}
                Firing::Blocked => continue,
                Firing::Overflow => return Err(Stop::Overflow),
                Firing::Outgrown { p, v } => {
                    // Widen p, repack what is stored, and expand this state again.
                    let wider = layout.widened(p, v, &at_limit);
                    at_limit.iter_mut().for_each(|a| *a = false);
                    repack(&layout, &wider, &mut store);
                    layout = wider;
                    stride = layout.stride;
                    // The old index goes before the new one is built, so
                    // the two are never held together.
                    drop(std::mem::take(&mut table));
                    table = index(&store, stride, states);
                    next = vec![0u8; stride + PAD];
                    packed = vec![0u8; stride + PAD];
                    edges = edges_before;
                    edge_to.truncate(edges);
                    edge_by.truncate(edges);
                    continue 'states;
                }
            }
            let target = intern(
                &mut table,
                &mut store,
                stride,
                &next[..stride],
                &mut states,
                options.max_states,
            )?;
            edges += 1;
            edge_to.push(target);
            edge_by.push(t);
        }
        edges_from.push(edges as u64);
        expanded += 1;
        if keep == Keep::GraphUntilDead && edges == edges_before {
            dead = Some(expanded - 1);
            break;
        }
        if expanded.is_multiple_of(DEADLINE_EVERY)
            && options.deadline.is_some_and(|d| Instant::now() >= d)
        {
            return Err(Stop::OutOfTime);
        }
        if expanded.is_multiple_of(PROGRESS_EVERY)
            && let Some(report) = options.progress.as_mut()
        {
            report(Progress {
                states,
                edges,
                elapsed: started.elapsed(),
            });
        }
    }
    Ok(Found {
        layout,
        store,
        graph: Graph {
            edges_from,
            edge_to,
            edge_by,
        },
        bounds,
        dead,
    })
}

impl StateSpace {
    /// Number of reachable markings.
    pub fn states(&self) -> usize {
        self.edges_from.len() - 1
    }

    /// Number of reachability-graph edges (firings between markings).
    pub fn edges(&self) -> usize {
        self.edge_to.len()
    }

    /// The successors of state `s`: (transition index, target state).
    pub fn successors(&self, s: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let (a, b) = (self.edges_from[s] as usize, self.edges_from[s + 1] as usize);
        (a..b).map(|e| (self.edge_by.get(e) as usize, self.edge_to[e] as usize))
    }

    /// The transition of `s`'s `k`-th edge, in the order of [`Self::successors`].
    pub(crate) fn label(&self, s: usize, k: usize) -> usize {
        self.edge_by.get(self.edges_from[s] as usize + k) as usize
    }

    /// The target states of `s`'s edges, in the order of [`Self::successors`].
    pub fn targets(&self, s: usize) -> &[u32] {
        &self.edge_to[self.edges_from[s] as usize..self.edges_from[s + 1] as usize]
    }

    /// Tokens of every place in state `s`.
    pub fn marking(&self, s: usize) -> Marking {
        let mut m = vec![0u32; self.layout.places()];
        self.layout.unpack(self.packed(s), &mut m);
        Marking(m)
    }

    /// The most tokens each place, and any marking, holds.
    pub fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn packed(&self, s: usize) -> &[u8] {
        &self.store[s * self.layout.stride..(s + 1) * self.layout.stride]
    }

    /// Bytes per stored marking.
    pub fn bytes_per_marking(&self) -> usize {
        self.layout.stride
    }
}
