//! Counting the state space breadth first on several threads.
//!
//! The markings of one level are shared out in chunks; each thread fires
//! its chunks' transitions and gathers the successors by shard of the
//! table, then puts a shard's batch in under the shard's lock, their homes
//! loaded together, so threads seldom wait for one another; what is new
//! makes the next level. Only markings are kept (no numbers, no edges), and
//! the level in flight beside them. A level too small to share is done by
//! one thread, with no other started.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use crate::explore::{Bounds, ExploreError, Options, Progress, StateCount};
use crate::layout::{
    Candidates, Compiled, Firing, Layout, PAD, compile, fire, initial_layout, repack,
};
use crate::markings::{EMPTY, MarkingTable, copy_marking, hash};
use crate::net::Net;

/// Shards of the table: enough that two threads seldom want the same one,
/// few enough that each grows like a table of its own.
const SHARDS: usize = 16;

/// Markings a thread takes from the level at a time.
const CHUNK: usize = 256;

/// Successors a thread gathers for a shard before it takes the shard's
/// lock and looks them all up.
const BATCH: usize = 32;

/// Counts every marking reachable from the initial one, and the firings
/// between them, without keeping the graph: breadth first on `threads`
/// threads (at least one), which find the same counts.
pub fn count_states(
    net: &Net,
    mut options: Options,
    threads: usize,
) -> Result<StateCount, ExploreError> {
    let options = &mut options;
    let compiled = compile(net);
    let candidates = Candidates::new(&compiled, net.places.len());
    let layout = initial_layout(net);
    let mut count = Count {
        compiled: &compiled,
        candidates: &candidates,
        shards: (0..SHARDS)
            .map(|_| Mutex::new(MarkingTable::new(layout.stride.max(1), 1)))
            .collect(),
        workers: (0..threads.max(1))
            .map(|_| Worker::new(&layout, compiled.len()))
            .collect(),
        layout,
    };
    count
        .run(&net.initial_marking().0, options)
        .map_err(|stop| match stop {
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

/// A place would hold `v`, more than its field holds.
struct Outgrown {
    p: usize,
    v: u32,
}

struct Count<'a> {
    compiled: &'a [Compiled],
    candidates: &'a Candidates,
    layout: Layout,
    shards: Vec<Mutex<MarkingTable>>,
    workers: Vec<Worker>,
}

/// One thread's buffers, kept from level to level, and what it found.
struct Worker {
    packed: Vec<u8>,
    next: Vec<u8>,
    current: Vec<u32>,
    enabled: Vec<u32>,
    /// Per shard, the successors gathered for it and their hashes.
    gathered: Vec<(Vec<u8>, Vec<u64>)>,
    /// The new markings it found in this level.
    found: Vec<u8>,
    edges: usize,
    bounds: Bounds,
    /// Places it saw at the most their fields hold.
    at_limit: Vec<bool>,
    stop: Option<Result<Outgrown, Stop>>,
}

impl Worker {
    fn new(layout: &Layout, transitions: usize) -> Worker {
        let places = layout.places();
        let stride = layout.stride.max(1);
        Worker {
            packed: vec![0; stride + PAD],
            next: vec![0; stride + PAD],
            current: vec![0; places],
            enabled: Vec::with_capacity(transitions),
            gathered: (0..SHARDS).map(|_| (Vec::new(), Vec::new())).collect(),
            found: Vec::new(),
            edges: 0,
            bounds: Bounds::new(places),
            at_limit: vec![false; places],
            stop: None,
        }
    }
}

impl Count<'_> {
    /// Counts level by level. A place that outgrows its field has every
    /// marking held repacked with it wider and the level done again: what
    /// the interrupted pass found new is kept, its firings are counted
    /// again.
    fn run(&mut self, initial: &[u32], options: &mut Options) -> Result<StateCount, Stop> {
        let started = Instant::now();
        let mut stride = self.layout.stride.max(1);
        let mut level = vec![0u8; stride + PAD];
        self.layout.pack(initial, &mut level);
        let h = hash(&level, stride);
        lock(&self.shards[shard(h)]).find_or_insert(h, &level, 1);
        level.truncate(stride);
        let mut states = 1usize;
        let mut edges = 0usize;
        // New markings an interrupted pass over this level found.
        let mut carried: Vec<u8> = Vec::new();
        while !level.is_empty() {
            self.level(&level);
            let mut found = std::mem::take(&mut carried);
            let mut level_edges = 0;
            let mut outgrown = None;
            let mut at_limit = vec![false; self.layout.places()];
            for worker in &mut self.workers {
                match worker.stop.take() {
                    Some(Ok(o)) => outgrown = Some(o),
                    Some(Err(stop)) => return Err(stop),
                    None => {}
                }
                for (a, b) in at_limit.iter_mut().zip(&worker.at_limit) {
                    *a |= b;
                }
                level_edges += std::mem::take(&mut worker.edges);
                found.append(&mut worker.found);
            }
            if let Some(Outgrown { p, v }) = outgrown {
                let wider = self.layout.widened(p, v, &at_limit);
                self.repack_all(&wider);
                repack(&self.layout, &wider, &mut level);
                repack(&self.layout, &wider, &mut found);
                self.workers.iter_mut().for_each(|w| {
                    *w = Worker {
                        bounds: w.bounds.clone(),
                        ..Worker::new(&wider, self.compiled.len())
                    }
                });
                self.layout = wider;
                stride = self.layout.stride.max(1);
                carried = found;
                continue;
            }
            edges += level_edges;
            level = found;
            states += level.len() / stride;
            if states > options.max_states {
                return Err(Stop::Limit);
            }
            if let Some(report) = options.progress.as_mut() {
                report(Progress {
                    states,
                    edges,
                    elapsed: started.elapsed(),
                });
            }
        }
        let mut bounds = Bounds::new(self.layout.places());
        for worker in &self.workers {
            bounds.join(&worker.bounds);
        }
        Ok(StateCount {
            states,
            edges,
            bounds,
            bytes_per_marking: self.layout.stride,
        })
    }

    /// Expands every marking of `level`: on every worker's thread when the
    /// level is large enough to share, else on this one alone.
    fn level(&mut self, level: &[u8]) {
        let stride = self.layout.stride.max(1);
        let taken = AtomicUsize::new(0);
        let stopped = AtomicBool::new(false);
        let shared = LevelWork {
            compiled: self.compiled,
            candidates: self.candidates,
            layout: &self.layout,
            shards: &self.shards,
            level,
            taken: &taken,
            stopped: &stopped,
        };
        let (first, others) = self.workers.split_first_mut().expect("one worker at least");
        if level.len() / stride < 2 * CHUNK || others.is_empty() {
            shared.expand(first);
            return;
        }
        std::thread::scope(|scope| {
            for worker in others {
                let shared = &shared;
                scope.spawn(move || shared.expand(worker));
            }
            shared.expand(first);
        });
    }

    /// Repacks every marking held with the `wider` layout. Every shard's
    /// markings are taken out first: repacked, a marking may hash to
    /// another shard.
    fn repack_all(&self, wider: &Layout) {
        let stride = wider.stride.max(1);
        let held: Vec<Vec<u8>> = self
            .shards
            .iter()
            .map(|shard| {
                let mut table = lock(shard);
                let mut markings = Vec::with_capacity(table.len() * self.layout.stride);
                for m in table.markings() {
                    markings.extend_from_slice(m);
                }
                *table = MarkingTable::with_room(stride, 1, table.len());
                markings
            })
            .collect();
        for mut markings in held {
            repack(&self.layout, wider, &mut markings);
            let count = markings.len() / stride;
            // Each marking is read with PAD spare bytes.
            markings.resize(markings.len() + PAD, 0);
            for i in 0..count {
                let m = &markings[i * stride..];
                let h = hash(m, stride);
                let mut table = lock(&self.shards[shard(h)]);
                if table.full() {
                    table.grow();
                }
                table.find_or_insert(h, m, 1);
            }
        }
    }
}

/// What the threads of one level share.
struct LevelWork<'a> {
    compiled: &'a [Compiled],
    candidates: &'a Candidates,
    layout: &'a Layout,
    shards: &'a [Mutex<MarkingTable>],
    level: &'a [u8],
    /// Markings of the level handed out so far.
    taken: &'a AtomicUsize,
    /// A worker stopped the level.
    stopped: &'a AtomicBool,
}

impl LevelWork<'_> {
    /// One worker's part of the level: chunks taken in turn, each
    /// marking's successors gathered and put in their shards.
    fn expand(&self, w: &mut Worker) {
        let layout = self.layout;
        let stride = layout.stride.max(1);
        let markings = self.level.len() / stride;
        'chunks: while !self.stopped.load(Ordering::Relaxed) {
            let from = self.taken.fetch_add(CHUNK, Ordering::Relaxed);
            if from >= markings {
                break;
            }
            let to = (from + CHUNK).min(markings);
            for m in self.level[from * stride..to * stride].chunks(stride) {
                w.packed[..stride].copy_from_slice(m);
                layout.unpack(&w.packed, &mut w.current);
                w.bounds.take(&w.current);
                w.enabled.clear();
                self.candidates
                    .enabled(self.compiled, &w.current, &mut w.enabled);
                for &t in &w.enabled {
                    copy_marking(&mut w.next, &w.packed, stride);
                    let current = &w.current;
                    let stop = match fire(
                        layout,
                        &self.compiled[t as usize],
                        |p| current[p],
                        &mut w.next,
                        &mut w.at_limit,
                    ) {
                        Firing::Next => None,
                        Firing::Blocked => continue,
                        Firing::Overflow => Some(Err(Stop::Overflow)),
                        Firing::Outgrown { p, v } => Some(Ok(Outgrown { p, v })),
                    };
                    if stop.is_some() {
                        w.stop = stop;
                        self.stopped.store(true, Ordering::Relaxed);
                        break 'chunks;
                    }
                    w.edges += 1;
                    let h = hash(&w.next, stride);
                    let k = shard(h);
                    let (gathered, hashes) = &mut w.gathered[k];
                    gathered.extend_from_slice(&w.next[..stride]);
                    hashes.push(h);
                    if hashes.len() == BATCH {
                        put(&self.shards[k], stride, &mut w.gathered[k], &mut w.found);
                    }
                }
            }
        }
        // What is gathered goes in either way: a level done again finds it.
        for (k, gathered) in w.gathered.iter_mut().enumerate() {
            put(&self.shards[k], stride, gathered, &mut w.found);
        }
    }
}

/// Puts the gathered successors in their shard, and those it did not hold
/// yet in `new`.
fn put(
    shard: &Mutex<MarkingTable>,
    stride: usize,
    gathered: &mut (Vec<u8>, Vec<u64>),
    new: &mut Vec<u8>,
) {
    let (markings, hashes) = gathered;
    if hashes.is_empty() {
        return;
    }
    // Each marking is read with PAD spare bytes.
    markings.resize(hashes.len() * stride + PAD, 0);
    let mut table = lock(shard);
    for &h in hashes.iter() {
        table.prefetch(h);
    }
    for (i, &h) in hashes.iter().enumerate() {
        if table.full() {
            table.grow();
        }
        let m = &markings[i * stride..];
        if table.find_or_insert(h, m, 1).1 == EMPTY {
            new.extend_from_slice(&m[..stride]);
        }
    }
    drop(table);
    markings.clear();
    hashes.clear();
}

/// The shard a marking of hash `h` belongs to: low bits, as a table takes
/// a marking's home from the high ones.
fn shard(h: u64) -> usize {
    h as usize % SHARDS
}

/// A shard's table. A thread that panicked holding it left no marking half
/// written (a marking is written after every check), and its panic ends
/// the count anyway.
fn lock(shard: &Mutex<MarkingTable>) -> MutexGuard<'_, MarkingTable> {
    shard.lock().unwrap_or_else(PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three counters no invariant bounds, each filled by a source
    /// transition up to its capacity of 40: 41³ markings, levels wide
    /// enough to share, and fields that outgrow 1, 2 and 4 bits on the way.
    #[test]
    fn every_thread_count_finds_every_marking_through_widening() {
        let mut net = Net::new("counters");
        for c in 0..3 {
            let p = net.add_place(&format!("c{c}"), 0).unwrap();
            net.places[p.0].capacity = Some(40);
            net.add_transition_with(&format!("fill{c}"), None, &[], &[(&format!("c{c}"), 1)])
                .unwrap();
        }
        for threads in [1, 2, 3] {
            let found = count_states(&net, Options::default(), threads).unwrap();
            assert_eq!(found.states, 41 * 41 * 41, "{threads} threads");
            // A marking fires each counter below 40: 40·41² firings each.
            assert_eq!(found.edges, 3 * 40 * 41 * 41, "{threads} threads");
            assert_eq!(found.bounds.places, [40, 40, 40]);
            assert_eq!(found.bounds.per_marking, 120);
        }
    }
}
