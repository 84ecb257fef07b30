//! Explicit state-space exploration: the reachability graph.
//!
//! States are numbered in breadth-first discovery order, so the store of
//! markings is also the BFS queue and successors are appended to a
//! compressed adjacency list (CSR) as each state is expanded — no separate
//! queue, no per-edge allocation. Markings are stored packed, one cell per
//! place, in the narrowest width (1, 2 or 4 bytes) the net's token counts fit:
//! exploration starts narrow and restarts wider only if a count overflows.

use std::hash::{Hash, Hasher};
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
    places: usize,
    cells: Cells,
    /// `edges_from[s]..edges_from[s + 1]` index the successors of state s.
    edges_from: Vec<u64>,
    /// Target state of each edge.
    edge_to: Vec<u32>,
    /// Transition fired on each edge.
    edge_by: Vec<u32>,
    /// Bytes the hash index of markings took at the end of exploration.
    index_bytes: usize,
}

/// Markings stored in the narrowest cell that holds every count.
#[derive(Debug, Clone)]
enum Cells {
    U8(Vec<u8>),
    U16(Vec<u16>),
    U32(Vec<u32>),
}

/// A token count cell.
trait Cell: Copy + Eq + Hash + Default + Send {
    const MAX: u32;
    fn get(self) -> u32;
    fn new(v: u32) -> Self;
}

macro_rules! cell {
    ($t:ty) => {
        impl Cell for $t {
            const MAX: u32 = <$t>::MAX as u32;
            fn get(self) -> u32 {
                u32::from(self)
            }
            fn new(v: u32) -> Self {
                v as $t
            }
        }
    };
}
cell!(u8);
cell!(u16);
cell!(u32);

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

/// Explores every marking reachable from the initial one.
pub fn explore(net: &Net, mut options: Options) -> Result<StateSpace, ExploreError> {
    let compiled = compile(net);
    let initial = net.initial_marking();
    let peak = initial.0.iter().copied().max().unwrap_or(0);
    let mut widest_first = if peak > u32::from(u16::MAX) {
        2
    } else if peak > u32::from(u8::MAX) {
        1
    } else {
        0
    };
    loop {
        let result = match widest_first {
            0 => run::<u8>(net, &compiled, &initial, &mut options).map(|(c, e)| (Cells::U8(c), e)),
            1 => {
                run::<u16>(net, &compiled, &initial, &mut options).map(|(c, e)| (Cells::U16(c), e))
            }
            _ => {
                run::<u32>(net, &compiled, &initial, &mut options).map(|(c, e)| (Cells::U32(c), e))
            }
        };
        match result {
            Ok((cells, (edges_from, edge_to, edge_by, index_bytes))) => {
                return Ok(StateSpace {
                    places: net.places.len(),
                    cells,
                    edges_from,
                    edge_to,
                    edge_by,
                    index_bytes,
                });
            }
            Err(Stop::Overflow) if widest_first < 2 => widest_first += 1,
            Err(Stop::Overflow) => return Err(ExploreError::TokenOverflow),
            Err(Stop::Limit) => {
                return Err(ExploreError::TooManyStates {
                    limit: options.max_states,
                });
            }
        }
    }
}

enum Stop {
    Overflow,
    Limit,
}

/// The CSR graph, and the bytes the marking index took.
type Edges = (Vec<u64>, Vec<u32>, Vec<u32>, usize);

fn hash_of<C: Cell>(m: &[C]) -> u64 {
    let mut h = FxHasher::default();
    m.hash(&mut h);
    h.finish()
}

fn run<C: Cell>(
    net: &Net,
    compiled: &[Compiled],
    initial: &Marking,
    options: &mut Options,
) -> Result<(Vec<C>, Edges), Stop> {
    let width = net.places.len();
    let started = Instant::now();
    let mut store: Vec<C> = initial.0.iter().map(|&v| C::new(v)).collect();
    let mut table: HashTable<u32> = HashTable::new();
    let mut states = 1usize;
    table.insert_unique(hash_of(&store[..width]), 0, |_| 0);
    let mut edges_from: Vec<u64> = vec![0];
    let mut edge_to: Vec<u32> = Vec::new();
    let mut edge_by: Vec<u32> = Vec::new();
    let mut next: Vec<C> = vec![C::default(); width];
    let mut current: Vec<C> = vec![C::default(); width];
    let mut expanded = 0usize;
    while expanded < states {
        let at = expanded * width;
        current.copy_from_slice(&store[at..at + width]);
        'transitions: for (t, tr) in compiled.iter().enumerate() {
            for &(p, w) in &tr.need {
                if current[p as usize].get() < w {
                    continue 'transitions;
                }
            }
            for &(p, w) in &tr.inhibit {
                if current[p as usize].get() >= w {
                    continue 'transitions;
                }
            }
            next.copy_from_slice(&current);
            for &(p, change, capacity) in &tr.delta {
                let v = i64::from(next[p as usize].get()) + change;
                if capacity.is_some_and(|cap| v > i64::from(cap)) {
                    continue 'transitions;
                }
                if v > i64::from(C::MAX) {
                    return Err(Stop::Overflow);
                }
                next[p as usize] = C::new(v as u32);
            }
            let hash = hash_of(&next);
            let found = table
                .find(hash, |&id| {
                    let s = id as usize * width;
                    store[s..s + width] == next[..]
                })
                .copied();
            let target = match found {
                Some(id) => id,
                None => {
                    if states >= options.max_states {
                        return Err(Stop::Limit);
                    }
                    let id = states as u32;
                    store.extend_from_slice(&next);
                    states += 1;
                    table.insert_unique(hash, id, |&id| {
                        let s = id as usize * width;
                        hash_of(&store[s..s + width])
                    });
                    id
                }
            };
            edge_to.push(target);
            edge_by.push(t as u32);
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
    let index_bytes = table.allocation_size();
    Ok((store, (edges_from, edge_to, edge_by, index_bytes)))
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
        let range = s * self.places..(s + 1) * self.places;
        Marking(match &self.cells {
            Cells::U8(c) => c[range].iter().map(|&v| u32::from(v)).collect(),
            Cells::U16(c) => c[range].iter().map(|&v| u32::from(v)).collect(),
            Cells::U32(c) => c[range].to_vec(),
        })
    }

    /// Calls `f` with each state's marking, without allocating per state.
    pub fn for_each_marking(&self, mut f: impl FnMut(&mut dyn Iterator<Item = u32>)) {
        let w = self.places.max(1);
        match &self.cells {
            Cells::U8(c) => c
                .chunks(w)
                .take(self.states())
                .for_each(|m| f(&mut m.iter().map(|&v| u32::from(v)))),
            Cells::U16(c) => c
                .chunks(w)
                .take(self.states())
                .for_each(|m| f(&mut m.iter().map(|&v| u32::from(v)))),
            Cells::U32(c) => c
                .chunks(w)
                .take(self.states())
                .for_each(|m| f(&mut m.iter().copied())),
        }
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
        self.places
            * match self.cells {
                Cells::U8(_) => 1,
                Cells::U16(_) => 2,
                Cells::U32(_) => 4,
            }
    }
}
