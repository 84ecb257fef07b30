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

use crate::net::{Marking, Net};

/// Why exploration stopped without a complete graph.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum ExploreError {
    #[error("stopped at the limit of {limit} states before the state space was complete")]
    TooManyStates { limit: usize },
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
}

impl Default for Options<'_> {
    fn default() -> Self {
        Options {
            max_states: usize::MAX,
            progress: None,
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
    edge_by: Vec<u32>,
    /// Bytes the hash index of markings took at the end of exploration.
    index_bytes: usize,
}

/// Where each place's count sits in a packed marking.
#[derive(Debug, Clone)]
struct Layout {
    /// Bit offset of each place.
    offset: Vec<u32>,
    /// Bits of each place (0 for a place that is provably always empty).
    width: Vec<u8>,
    /// Bytes per marking.
    stride: usize,
}

/// Bytes of slack after a packed marking, so a place is read and written as
/// one unaligned 8-byte word.
const PAD: usize = 8;

impl Layout {
    fn new(width: Vec<u8>) -> Layout {
        let mut offset = Vec::with_capacity(width.len());
        let mut bits = 0u32;
        for &w in &width {
            offset.push(bits);
            bits += u32::from(w);
        }
        Layout {
            offset,
            width,
            stride: bits.div_ceil(8) as usize,
        }
    }

    /// The same layout with place `p` wide enough for `v`, and every place
    /// in `also` (which reached its own limit) likewise doubled, so places
    /// that grow together are repacked together.
    fn widened(&self, p: usize, v: u32, also: &[bool]) -> Layout {
        let mut width = self.width.clone();
        for (q, w) in width.iter_mut().enumerate() {
            if q == p || also[q] {
                *w = ((*w).max(1) * 2).min(32);
            }
        }
        width[p] = width[p].max(bits(v));
        Layout::new(width)
    }

    /// The largest count place `p` can hold.
    fn max(&self, p: usize) -> u32 {
        match self.width[p] {
            32.. => u32::MAX,
            w => (1u32 << w) - 1,
        }
    }

    fn get(&self, packed: &[u8], p: usize) -> u32 {
        let bit = self.offset[p] as usize;
        let at = bit / 8;
        let word = match packed.get(at..at + 8) {
            // The common case: a padded buffer, one unaligned load.
            Some(eight) => u64::from_le_bytes(eight.try_into().expect("eight bytes")),
            None => {
                let mut word = [0u8; 8];
                word[..packed.len() - at].copy_from_slice(&packed[at..]);
                u64::from_le_bytes(word)
            }
        };
        ((word >> (bit % 8)) & ((1u64 << self.width[p]) - 1)) as u32
    }

    /// Writes `v` (which fits) into place `p` of `packed`, which has PAD spare bytes.
    fn set(&self, packed: &mut [u8], p: usize, v: u32) {
        let bit = self.offset[p] as usize;
        let at = bit / 8;
        let mut word = [0u8; 8];
        word.copy_from_slice(&packed[at..at + 8]);
        let mask = ((1u64 << self.width[p]) - 1) << (bit % 8);
        let w = (u64::from_le_bytes(word) & !mask) | (u64::from(v) << (bit % 8));
        packed[at..at + 8].copy_from_slice(&w.to_le_bytes());
    }

    fn unpack(&self, packed: &[u8], out: &mut [u32]) {
        for (p, slot) in out.iter_mut().enumerate() {
            *slot = self.get(packed, p);
        }
    }
}

/// A transition compiled for fast firing.
struct Compiled {
    /// (place, weight) that must be present.
    need: Vec<(u32, u32)>,
    /// (place, weight): enabled only while the place holds fewer.
    inhibit: Vec<(u32, u32)>,
    /// (place, change) when it fires, with its capacity if any.
    delta: Vec<(u32, i64, Option<u32>)>,
}

fn compile(net: &Net) -> Vec<Compiled> {
    net.transitions
        .iter()
        .map(|t| {
            let mut delta: Vec<(u32, i64, Option<u32>)> = Vec::new();
            for a in &t.pre {
                delta.push((a.place.0 as u32, -i64::from(a.weight), None));
            }
            for a in &t.post {
                match delta.iter_mut().find(|d| d.0 == a.place.0 as u32) {
                    Some(d) => d.1 += i64::from(a.weight),
                    None => delta.push((a.place.0 as u32, i64::from(a.weight), None)),
                }
            }
            delta.retain(|d| d.1 != 0);
            for d in &mut delta {
                d.2 = net.places[d.0 as usize].capacity;
            }
            Compiled {
                need: t.pre.iter().map(|a| (a.place.0 as u32, a.weight)).collect(),
                inhibit: t
                    .inhibit
                    .iter()
                    .map(|a| (a.place.0 as u32, a.weight))
                    .collect(),
                delta,
            }
        })
        .collect()
}

/// How often progress is reported, in expanded states.
const PROGRESS_EVERY: usize = 1 << 18;

/// Rows the invariant computation may use while looking for place bounds.
const BOUND_ROWS: usize = 5_000;

/// Bits needed to write `v`.
fn bits(v: u32) -> u8 {
    (32 - v.leading_zeros()) as u8
}

/// Per-place bounds the minimal P-invariants prove: y·m = y·m0 for every
/// reachable m, so m(p) ≤ y·m0 / y(p) for every invariant y covering p.
fn proven_bounds(net: &Net) -> Vec<Option<u32>> {
    let mut bounds = vec![None; net.places.len()];
    let Ok(invariants) = crate::invariants::p_invariants(net, BOUND_ROWS) else {
        return bounds;
    };
    for y in invariants {
        let total: u64 = y
            .iter()
            .map(|&(p, k)| k * u64::from(net.places[p].initial))
            .sum();
        for &(p, k) in &y {
            let b = u32::try_from(total / k).unwrap_or(u32::MAX);
            bounds[p] = Some(bounds[p].map_or(b, |old: u32| old.min(b)));
        }
    }
    bounds
}

/// Explores every marking reachable from the initial one.
pub fn explore(net: &Net, mut options: Options) -> Result<StateSpace, ExploreError> {
    let compiled = compile(net);
    let initial = net.initial_marking();
    let width = proven_bounds(net)
        .iter()
        .zip(&initial.0)
        .map(|(bound, &m)| bound.map_or(bits(m).max(1), bits))
        .collect();
    run(Layout::new(width), &compiled, &initial, &mut options).map_err(|stop| match stop {
        Stop::Overflow => ExploreError::TokenOverflow,
        Stop::Limit => ExploreError::TooManyStates {
            limit: options.max_states,
        },
    })
}

enum Stop {
    Overflow,
    Limit,
}

fn hash_of(m: &[u8]) -> u64 {
    let mut h = FxHasher::default();
    h.write(m);
    h.finish()
}

/// Markings `store` packed in `from`, repacked in `to`.
fn repack(from: &Layout, to: &Layout, store: &[u8]) -> Vec<u8> {
    let states = store.len().checked_div(from.stride).unwrap_or(0);
    let mut out = vec![0u8; states * to.stride + PAD];
    let mut m = vec![0u32; from.width.len()];
    for s in 0..states {
        from.unpack(&store[s * from.stride..(s + 1) * from.stride], &mut m);
        for (p, &v) in m.iter().enumerate() {
            to.set(&mut out[s * to.stride..], p, v);
        }
    }
    out.truncate(states * to.stride);
    out
}

fn run(
    mut layout: Layout,
    compiled: &[Compiled],
    initial: &Marking,
    options: &mut Options,
) -> Result<StateSpace, Stop> {
    let mut stride = layout.stride;
    let started = Instant::now();
    let mut next = vec![0u8; stride + PAD];
    for (p, &v) in initial.0.iter().enumerate() {
        layout.set(&mut next, p, v);
    }
    let mut store: Vec<u8> = next[..stride].to_vec();
    let mut table: HashTable<u32> = HashTable::new();
    let mut states = 1usize;
    table.insert_unique(hash_of(&store[..stride]), 0, |_| 0);
    let mut edges_from: Vec<u64> = vec![0];
    let mut edge_to: Vec<u32> = Vec::new();
    let mut edge_by: Vec<u32> = Vec::new();
    let mut current = vec![0u32; layout.width.len()];
    let mut packed = vec![0u8; stride + PAD];
    let mut expanded = 0usize;
    // Each transition is listed under its first input place: only those under
    // a marked place (and those with no input) can be enabled.
    let mut listed_under: Vec<Vec<u32>> = vec![Vec::new(); layout.width.len()];
    let mut always: Vec<u32> = Vec::new();
    for (t, tr) in compiled.iter().enumerate() {
        match tr.need.first() {
            Some(&(p, _)) => listed_under[p as usize].push(t as u32),
            None => always.push(t as u32),
        }
    }
    let mut candidates: Vec<u32> = Vec::with_capacity(compiled.len());
    // Places that have been seen full: the next overflow widens them too.
    let mut at_limit = vec![false; layout.width.len()];
    'states: while expanded < states {
        let at = expanded * stride;
        packed[..stride].copy_from_slice(&store[at..at + stride]);
        layout.unpack(&packed, &mut current);
        candidates.clear();
        candidates.extend_from_slice(&always);
        for (p, &v) in current.iter().enumerate() {
            if v > 0 {
                candidates.extend_from_slice(&listed_under[p]);
            }
        }
        // In transition order, so the numbering of states does not depend on this filter.
        candidates.sort_unstable();
        'transitions: for &t in &candidates {
            let tr = &compiled[t as usize];
            for &(p, w) in &tr.need {
                if current[p as usize] < w {
                    continue 'transitions;
                }
            }
            for &(p, w) in &tr.inhibit {
                if current[p as usize] >= w {
                    continue 'transitions;
                }
            }
            next.copy_from_slice(&packed);
            for &(p, change, capacity) in &tr.delta {
                let p = p as usize;
                let v = i64::from(current[p]) + change;
                if capacity.is_some_and(|cap| v > i64::from(cap)) {
                    continue 'transitions;
                }
                if v == i64::from(layout.max(p)) {
                    at_limit[p] = true;
                }
                if v > i64::from(layout.max(p)) {
                    if layout.width[p] >= 32 {
                        return Err(Stop::Overflow);
                    }
                    // Widen p, repack what is stored, and expand this state again.
                    let wider = layout.widened(p, v as u32, &at_limit);
                    at_limit.iter_mut().for_each(|a| *a = false);
                    store = repack(&layout, &wider, &store);
                    layout = wider;
                    stride = layout.stride;
                    table = HashTable::with_capacity(states);
                    for id in 0..states {
                        let s = id * stride;
                        table.insert_unique(hash_of(&store[s..s + stride]), id as u32, |&id| {
                            let s = id as usize * stride;
                            hash_of(&store[s..s + stride])
                        });
                    }
                    next = vec![0u8; stride + PAD];
                    packed = vec![0u8; stride + PAD];
                    let first_edge = edges_from[expanded] as usize;
                    edge_to.truncate(first_edge);
                    edge_by.truncate(first_edge);
                    continue 'states;
                }
                layout.set(&mut next, p, v as u32);
            }
            let hash = hash_of(&next[..stride]);
            let found = table
                .find(hash, |&id| {
                    let s = id as usize * stride;
                    store[s..s + stride] == next[..stride]
                })
                .copied();
            let target = match found {
                Some(id) => id,
                None => {
                    if states >= options.max_states {
                        return Err(Stop::Limit);
                    }
                    let id = states as u32;
                    store.extend_from_slice(&next[..stride]);
                    states += 1;
                    table.insert_unique(hash, id, |&id| {
                        let s = id as usize * stride;
                        hash_of(&store[s..s + stride])
                    });
                    id
                }
            };
            edge_to.push(target);
            edge_by.push(t);
        }
        edges_from.push(edge_to.len() as u64);
        expanded += 1;
        if expanded.is_multiple_of(PROGRESS_EVERY)
            && let Some(report) = options.progress.as_mut()
        {
            report(Progress {
                states,
                edges: edge_to.len(),
                elapsed: started.elapsed(),
            });
        }
    }
    Ok(StateSpace {
        layout,
        store,
        edges_from,
        edge_to,
        edge_by,
        index_bytes: table.allocation_size(),
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
        self.edge_by[a..b]
            .iter()
            .zip(&self.edge_to[a..b])
            .map(|(&t, &to)| (t as usize, to as usize))
    }

    /// The target states of `s`'s edges, in the order of [`Self::successors`].
    pub fn targets(&self, s: usize) -> &[u32] {
        &self.edge_to[self.edges_from[s] as usize..self.edges_from[s + 1] as usize]
    }

    /// Tokens of every place in state `s`.
    pub fn marking(&self, s: usize) -> Marking {
        let mut m = vec![0u32; self.layout.width.len()];
        self.layout.unpack(self.packed(s), &mut m);
        Marking(m)
    }

    /// Calls `f` with each state's marking, reusing one buffer.
    pub fn for_each_marking(&self, mut f: impl FnMut(&[u32])) {
        let mut m = vec![0u32; self.layout.width.len()];
        for s in 0..self.states() {
            self.layout.unpack(self.packed(s), &mut m);
            f(&m);
        }
    }

    fn packed(&self, s: usize) -> &[u8] {
        &self.store[s * self.layout.stride..(s + 1) * self.layout.stride]
    }

    /// Bytes of the state store: the packed markings plus the hash index
    /// that found them (the figure explicit-state tools quote per state).
    pub fn store_bytes(&self) -> usize {
        self.states() * self.bytes_per_marking() + self.index_bytes
    }

    /// Bytes of the graph's edges, which liveness and reversibility need.
    pub fn graph_bytes(&self) -> usize {
        self.edges_from.len() * 8 + (self.edge_to.len() + self.edge_by.len()) * 4
    }

    /// Bytes per stored marking.
    pub fn bytes_per_marking(&self) -> usize {
        self.layout.stride
    }
}
