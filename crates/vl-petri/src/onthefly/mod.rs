//! Analysis on the fly: Tarjan's algorithm run inside a depth-first search
//! of the state space, so liveness, reversibility and deadlocks are known
//! when the search ends and no edge is ever stored.
//!
//! Memory goes to the markings, and little else:
//! - They live in the hash table itself ([`table`]): each slot holds a
//!   packed marking and its number, the order it was reached in, so
//!   following an edge costs one probe. The table grows in place by halves
//!   and thirds, never holding itself twice.
//! - The search carries the top state's marking along the path, unpacked
//!   and packed, changing it by a transition's effect on each step down and
//!   back. No marking is ever unpacked from the table, so places the others
//!   determine need no field at all ([`search_layout`]).
//! - A frame of the path is a low number and three flags, 4 bytes, and
//!   what it has left to fire takes a few bits ([`pending`]): on a strongly
//!   connected graph the path runs as deep as the graph is large.
//! - The numbers of the states whose component is still open form a few
//!   runs, so whether a state's component has closed is read off its
//!   number, and closing one writes nothing.

use std::time::Instant;

use crate::explore::{Bounds, Options, PROGRESS_EVERY, Progress};
use crate::layout::{Candidates, Compiled, Firing, Layout, PAD, compile, fire, search_layout};
use crate::liveness::Liveness;
use crate::net::Net;

mod pending;

use crate::markings::{EMPTY, MarkingTable, Stack, copy_marking};
use pending::Pending;

/// What one search found.
pub(crate) struct Found {
    pub(crate) states: usize,
    pub(crate) edges: usize,
    pub(crate) bounds: Bounds,
    /// Some marking enables nothing.
    pub(crate) dead: bool,
    /// Strongly connected components of the reachability graph.
    pub(crate) components: usize,
    pub(crate) liveness: Vec<Liveness>,
    pub(crate) bytes_per_marking: usize,
}

/// Why a search stopped early.
pub(crate) enum Stop {
    /// A place outgrew its field: search again with it wider.
    Widen {
        p: usize,
        v: u32,
    },
    /// More numbers than 3 bytes hold: search again with 4.
    Renumber,
    Overflow,
    Limit,
}

/// The most states one search numbers: a frame holds a number in 29 bits.
pub(crate) const MOST_STATES: usize = 1 << 29;

/// Searches the state space of `net` depth first and reads its components
/// as they close. A place that outgrows its field starts the search again
/// with a wider layout (places no invariant bounds are found full early),
/// and numbers past what 3 bytes hold start it again with 4-byte numbers.
pub(crate) fn read(net: &Net, options: &mut Options) -> Result<Found, Stop> {
    let compiled = compile(net);
    let initial = net.initial_marking();
    let mut layout = search_layout(net);
    give_back_freed_memory();
    let mut at_limit = vec![false; net.places.len()];
    let mut number_bytes = 3;
    loop {
        match Search::new(&layout, &compiled, &mut at_limit, number_bytes).run(&initial.0, options)
        {
            Err(Stop::Widen { p, v }) => {
                layout = layout.widened(p, v, &at_limit);
                at_limit.iter_mut().for_each(|a| *a = false);
            }
            Err(Stop::Renumber) => number_bytes = 4,
            other => return other,
        }
    }
}

/// Returns to the system the heap memory the invariant computations and
/// parsing freed before the search (glibc keeps freed memory that is not
/// at the heap's end, which would otherwise count for the whole search).
fn give_back_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases pages of free chunks.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// The largest number 3 bytes hold (0 is EMPTY).
const MOST_IN_3: u32 = (1 << 24) - 1;

/// A state on the depth-first path: its low number (the least number of an
/// open state it is known to reach), with three flags in the top bits. A
/// state's own number is in the table and never changes, so a frame needs
/// no slot, and the table may move states as it grows; a frame is 4
/// bytes, for on a strongly connected graph the path runs as deep as the
/// graph is large.
#[derive(Clone, Copy)]
struct Frame(u32);

/// The state fired something.
const FIRED: u32 = 1 << 31;
/// An edge from the state, or from its component below it, leaves the component.
const EXITS: u32 = 1 << 30;
/// The state reaches a state reached before it: it is not its component's root.
const BELOW: u32 = 1 << 29;
const FLAGS: u32 = FIRED | EXITS | BELOW;

impl Frame {
    fn low(self) -> u32 {
        self.0 & !FLAGS
    }

    fn has(self, flag: u32) -> bool {
        self.0 & flag != 0
    }

    /// The frame with its low number `low`, and BELOW.
    fn lowered(self, low: u32) -> Frame {
        Frame(self.0 & FLAGS | BELOW | low)
    }
}

/// Successors looked up together, so their cache misses overlap.
const BATCH: usize = 16;

struct Search<'a> {
    layout: &'a Layout,
    compiled: &'a [Compiled],
    at_limit: &'a mut [bool],
    stride: usize,
    table: MarkingTable,
    candidates: Candidates,
    /// The path, a [`Frame`] each.
    frames: Stack,
    pending: Pending,
    /// The numbers of the states whose component is still open, as runs
    /// `[start, end)` in order: a state's component has closed exactly
    /// when its number is in none.
    open: Vec<(u32, u32)>,
    /// The number the next new state gets.
    next: u32,
    /// The largest number 3 bytes hold (MOST_IN_3 but in a test).
    most_in_3: u32,
    /// The top state's marking: each place's count, and packed.
    current: Vec<u32>,
    packed: Vec<u8>,
    /// Tokens in `current`.
    tokens: u64,
    enabled: Vec<u32>,
    bounds: Bounds,
    states: usize,
    edges: usize,
    dead: bool,
    components: usize,
    /// Per transition: it fires; it fires inside a component.
    fires: Vec<bool>,
    cycles: Vec<bool>,
    /// Per transition: the largest number given out when it last fired.
    latest: Vec<u32>,
    /// The transitions that fire inside every terminal component so far
    /// (None before the first).
    in_every_terminal: Option<Vec<u32>>,
}

impl<'a> Search<'a> {
    fn new(
        layout: &'a Layout,
        compiled: &'a [Compiled],
        at_limit: &'a mut [bool],
        number_bytes: usize,
    ) -> Search<'a> {
        let places = layout.places();
        let transitions = compiled.len();
        // A net with one marking packs it in no bytes; a byte keeps the
        // table counting.
        let stride = layout.stride.max(1);
        Search {
            layout,
            compiled,
            at_limit,
            stride,
            table: MarkingTable::new(stride, number_bytes),
            candidates: Candidates::new(compiled, places),
            frames: Stack::new(4),
            pending: Pending::new(transitions),
            open: Vec::new(),
            next: 1,
            most_in_3: MOST_IN_3,
            current: vec![0; places],
            packed: vec![0; stride + PAD],
            tokens: 0,
            enabled: Vec::with_capacity(transitions),
            bounds: Bounds::new(places),
            states: 0,
            edges: 0,
            dead: false,
            components: 0,
            fires: vec![false; transitions],
            cycles: vec![false; transitions],
            latest: vec![0; transitions],
            in_every_terminal: None,
        }
    }

    /// The largest number the table's numbers hold.
    fn most_number(&self) -> u32 {
        match self.table.number_bytes {
            3 => self.most_in_3,
            _ => MOST_STATES as u32,
        }
    }

    fn frame(&self, k: usize) -> Frame {
        Frame(self.frames.get(k) as u32)
    }

    fn top(&self) -> Frame {
        self.frame(self.frames.len() - 1)
    }

    fn set_top(&mut self, frame: Frame) {
        self.frames.set(self.frames.len() - 1, u64::from(frame.0));
    }

    fn flag_top(&mut self, flags: u32) {
        self.set_top(Frame(self.top().0 | flags));
    }

    /// Whether the state numbered `n` is in a component still open.
    fn is_open(&self, n: u32) -> bool {
        match self.open.last() {
            Some(&(start, end)) if n >= start => n < end,
            _ => {
                let after = self.open.partition_point(|&(start, _)| start <= n);
                after > 0 && n < self.open[after - 1].1
            }
        }
    }

    fn run(mut self, initial: &[u32], options: &mut Options) -> Result<Found, Stop> {
        let started = Instant::now();
        let stride = self.stride;
        let most_states = options.max_states.min(MOST_STATES);
        // The batch's successors, their hashes, and whether each is an edge.
        let mut batch = vec![0u8; BATCH * stride + PAD];
        let mut hashes = [0u64; BATCH];
        let mut edge = [false; BATCH];
        let mut firing = [0u32; BATCH];
        self.current.copy_from_slice(initial);
        self.layout.pack(initial, &mut self.packed);
        self.bounds.take(&self.current);
        self.tokens = self.bounds.per_marking;
        let hash = self.table.hash(&self.packed);
        self.table.find_or_insert(hash, &self.packed, self.next);
        self.enter();
        while self.frames.len() > 0 {
            let n = self.pending.peek(&mut firing);
            if n == 0 {
                self.leave();
                continue;
            }
            let layout = self.layout;
            for j in 0..n {
                let t = firing[j] as usize;
                let next = &mut batch[j * stride..(j + 1) * stride + PAD];
                copy_marking(next, &self.packed, stride);
                let current = &self.current;
                edge[j] = match fire(
                    layout,
                    &self.compiled[t],
                    |p| current[p],
                    next,
                    self.at_limit,
                ) {
                    Firing::Next => true,
                    Firing::Blocked => false,
                    Firing::Overflow => return Err(Stop::Overflow),
                    Firing::Outgrown { p, v } => return Err(Stop::Widen { p, v }),
                };
                if edge[j] {
                    hashes[j] = self.table.hash(next);
                    self.table.prefetch(hashes[j]);
                }
            }
            for j in 0..n {
                let t = firing[j];
                if !edge[j] {
                    self.pending.take();
                    continue;
                }
                self.edges += 1;
                self.fires[t as usize] = true;
                self.latest[t as usize] = self.next - 1;
                if self.table.full() {
                    self.table.grow();
                }
                let next = &batch[j * stride..(j + 1) * stride + PAD];
                let (_, number) = self.table.find_or_insert(hashes[j], next, self.next);
                let flags = match number {
                    EMPTY => {
                        if self.states >= most_states {
                            return Err(Stop::Limit);
                        }
                        if self.next >= self.most_number() {
                            return Err(Stop::Renumber);
                        }
                        self.pending.descend(t);
                        self.step(t, next);
                        self.flag_top(FIRED);
                        self.enter();
                        if self.states.is_multiple_of(PROGRESS_EVERY)
                            && let Some(report) = options.progress.as_mut()
                        {
                            report(Progress {
                                states: self.states,
                                edges: self.edges,
                                elapsed: started.elapsed(),
                            });
                        }
                        // The rest of the batch waits for the return.
                        break;
                    }
                    number if self.is_open(number) => {
                        // An edge back into the open part: the top state
                        // reaches as low as the target.
                        self.cycles[t as usize] = true;
                        let top = self.top();
                        if number < top.low() {
                            self.set_top(top.lowered(number));
                        }
                        FIRED
                    }
                    _ => FIRED | EXITS,
                };
                self.pending.take();
                self.flag_top(flags);
            }
        }
        Ok(self.reading())
    }

    /// What the search found, each transition's liveness read off the
    /// terminal components and the cycles it closed.
    fn reading(self) -> Found {
        let transitions = self.compiled.len();
        let mut l4 = vec![false; transitions];
        for &t in self.in_every_terminal.iter().flatten() {
            l4[t as usize] = true;
        }
        let liveness = (0..transitions)
            .map(|t| Liveness::of(l4[t], self.cycles[t], self.fires[t]))
            .collect();
        Found {
            states: self.states,
            edges: self.edges,
            bounds: self.bounds,
            dead: self.dead,
            components: self.components,
            liveness,
            bytes_per_marking: self.layout.stride,
        }
    }

    /// Moves the top marking down the edge `t` to `next` (its packing).
    fn step(&mut self, t: u32, next: &[u8]) {
        let tr = &self.compiled[t as usize];
        for &(p, change, _) in tr.changes() {
            let v = &mut self.current[p as usize];
            *v = (i64::from(*v) + change) as u32;
            if change > 0 {
                let bound = &mut self.bounds.places[p as usize];
                *bound = (*bound).max(*v);
            }
            self.tokens = (self.tokens as i64 + change) as u64;
        }
        self.bounds.per_marking = self.bounds.per_marking.max(self.tokens);
        copy_marking(&mut self.packed, next, self.stride);
    }

    /// Moves the top marking back up the edge `t`.
    fn step_back(&mut self, t: u32) {
        let tr = &self.compiled[t as usize];
        for &(p, change, _) in tr.changes() {
            let p = p as usize;
            self.current[p] = (i64::from(self.current[p]) - change) as u32;
            self.tokens = (self.tokens as i64 - change) as u64;
            self.layout.set(&mut self.packed, p, self.current[p]);
        }
    }

    /// Puts the state just numbered `next`, whose marking is the top one
    /// now, on the path with its enabled transitions.
    fn enter(&mut self) {
        let n = self.next;
        match self.open.last_mut() {
            Some(run) if run.1 == n => run.1 += 1,
            _ => self.open.push((n, n + 1)),
        }
        self.next += 1;
        self.enabled.clear();
        self.candidates
            .enabled(self.compiled, &self.current, &mut self.enabled);
        self.pending.push(&self.enabled);
        self.frames.push(u64::from(n));
        self.states += 1;
    }

    /// Ends the search from the top frame: closes its component if it is
    /// the component's root, and tells its parent what the tree edge was.
    fn leave(&mut self) {
        let v = Frame(self.frames.pop().expect("a frame is open") as u32);
        let by = self.pending.pop();
        self.dead |= !v.has(FIRED);
        let low = v.low();
        let root = !v.has(BELOW);
        if root {
            // A root's low number is its own: its component is every open
            // state numbered from it on.
            if !v.has(EXITS) {
                self.terminal(low);
            }
            while let Some(run) = self.open.last_mut() {
                if run.0 >= low {
                    self.open.pop();
                } else {
                    run.1 = run.1.min(low);
                    break;
                }
            }
            self.components += 1;
        }
        let (Some(_), Some(by)) = (self.frames.last(), by) else {
            return;
        };
        self.step_back(by);
        let (compiled, current, candidates) = (self.compiled, &self.current, &self.candidates);
        self.pending
            .resume(by, |list| candidates.enabled(compiled, current, list));
        let mut flags = 0;
        if root {
            flags |= EXITS;
        } else {
            // The tree edge stays inside the component, and the parent
            // reaches as low as v does.
            self.cycles[by as usize] = true;
            if v.has(EXITS) {
                flags |= EXITS;
            }
            let parent = self.top();
            if low < parent.low() {
                self.set_top(parent.lowered(low));
            }
        }
        self.flag_top(flags);
    }

    /// Counts the component numbered from `root` on, which no edge leaves.
    /// No component closed inside it (it would be one an edge leads to),
    /// so every state numbered from `root` on is in it, and a transition
    /// fires inside it exactly when it last fired since `root` was reached.
    fn terminal(&mut self, root: u32) {
        let latest = &self.latest;
        let inside = |t: u32| latest[t as usize] >= root;
        match &mut self.in_every_terminal {
            Some(every) => every.retain(|&t| inside(t)),
            None => {
                self.in_every_terminal = Some(
                    (0..self.compiled.len() as u32)
                        .filter(|&t| inside(t))
                        .collect(),
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers past what 3 bytes hold start the search again with 4: here
    /// with that most lowered to 100, on a ring of 300 states.
    #[test]
    fn more_states_than_three_bytes_number_take_four() {
        let mut net = Net::new("ring");
        for k in 0..300 {
            net.add_place(&format!("p{k}"), u32::from(k == 0)).unwrap();
        }
        for k in 0..300 {
            let (from, to) = (format!("p{k}"), format!("p{}", (k + 1) % 300));
            net.add_transition_with(&format!("t{k}"), None, &[(&from, 1)], &[(&to, 1)])
                .unwrap();
        }
        let compiled = compile(&net);
        let layout = search_layout(&net);
        let initial = net.initial_marking();
        let mut at_limit = vec![false; net.places.len()];
        let search = |bytes, at_limit: &mut [bool]| {
            let mut search = Search::new(&layout, &compiled, at_limit, bytes);
            search.most_in_3 = 100;
            search.run(&initial.0, &mut Options::default())
        };
        assert!(matches!(search(3, &mut at_limit), Err(Stop::Renumber)));
        let reading = search(4, &mut at_limit)
            .ok()
            .expect("4 bytes number them all");
        assert_eq!((reading.states, reading.components), (300, 1));
    }

    use proptest::prelude::*;

    use crate::analysis::analyze;
    use crate::explore::explore;
    use crate::net::ArcKind;

    /// Small random nets (weights, inhibitor arcs, capacities) with 64 more
    /// transitions that never fire, so the path keeps lists, not masks.
    fn net_of_many_transitions() -> impl Strategy<Value = Net> {
        let arc = (0usize..4, 1u32..=2, 0u8..10);
        (
            proptest::collection::vec(0u32..=2, 4),
            proptest::collection::vec(proptest::option::weighted(0.2, 1u32..=3), 4),
            proptest::collection::vec(proptest::collection::vec(arc, 1..5), 1..7),
        )
            .prop_map(|(initial, capacities, transitions)| {
                let mut net = Net::new("many");
                for (p, (&m, &cap)) in initial.iter().zip(&capacities).enumerate() {
                    let p = net.add_place(&format!("p{p}"), m).unwrap();
                    net.places[p.0].capacity = cap.map(|c| c.max(m));
                }
                net.add_place("never", 0).unwrap();
                for (t, arcs) in transitions.iter().enumerate() {
                    let id = net.add_transition(&format!("t{t}"), None).unwrap();
                    for &(p, w, kind) in arcs {
                        let kind = match kind {
                            0..=4 => ArcKind::Input,
                            5..=8 => ArcKind::Output,
                            _ => ArcKind::Inhibitor,
                        };
                        net.add_arc(kind, &format!("p{p}"), id, w).unwrap();
                    }
                }
                for k in 0..64 {
                    net.add_transition_with(
                        &format!("dead{k}"),
                        None,
                        &[("never", 1)],
                        &[("p0", 1)],
                    )
                    .unwrap();
                }
                net
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// With lists saved for every frame, or for none (each made again
        /// on the return), the search reads what the stored graph says.
        #[test]
        fn lists_saved_or_made_again_read_the_same(net in net_of_many_transitions()) {
            let limit = || Options { max_states: 2000, progress: None, deadline: None };
            let Ok(space) = explore(&net, limit()) else {
                return Ok(());
            };
            let stored = analyze(&net, &space);
            let compiled = compile(&net);
            let layout = search_layout(&net);
            for depth in [usize::MAX, 0, 1] {
                let mut at_limit = vec![false; net.places.len()];
                let mut search = Search::new(&layout, &compiled, &mut at_limit, 4);
                search.pending = Pending::new(compiled.len()).saving(depth);
                let Ok(reading) = search.run(&net.initial_marking().0, &mut limit()) else {
                    // A place outgrew the layout: read() widens it; the
                    // stored graph's test covers that.
                    continue;
                };
                prop_assert_eq!(reading.states, stored.states);
                prop_assert_eq!(reading.edges, stored.edges);
                prop_assert_eq!(reading.dead, stored.deadlock);
                prop_assert_eq!(reading.components == 1, stored.reversible);
                prop_assert_eq!(&reading.liveness, &stored.liveness);
                prop_assert_eq!(&reading.bounds.places, &stored.place_bounds);
            }
        }
    }
}
