//! Analysis on the fly: Tarjan's algorithm run inside a depth-first search
//! of the state space, so liveness, reversibility and deadlocks are known
//! when the search ends and no edge is ever stored.
//!
//! The markings live in the hash table itself (open addressing, linear
//! probing): each slot holds a packed marking and its Tarjan number, so
//! following an edge costs one probe, where a store with a separate index
//! costs a probe and then a read elsewhere. The table doubles in place. The
//! depth-first path and Tarjan's stack hold copies of their markings, not
//! slots, so nothing has to be renumbered when the table grows.

use std::hash::Hasher;
use std::time::Instant;

use rustc_hash::FxHasher;

use crate::analysis::Liveness;
use crate::explore::{
    Bounds, Candidates, Compiled, Fired, Labels, Layout, Options, PAD, PROGRESS_EVERY, Progress,
    compile, fire, initial_layout,
};
use crate::net::Net;

/// What one search found.
pub(crate) struct Reading {
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
    /// More states than 3-byte numbers count: search again with 4.
    Renumber,
    Overflow,
    Limit,
}

/// Searches the state space of `net` depth first and reads its components
/// as they close. A place that outgrows its field starts the search again
/// with a wider layout (places no invariant bounds are found full early),
/// and a state space past NUMBERS_IN_3 states with 4-byte Tarjan numbers.
pub(crate) fn read(net: &Net, options: &mut Options) -> Result<Reading, Stop> {
    let compiled = compile(net);
    let initial = net.initial_marking();
    let mut layout = initial_layout(net);
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

/// States whose Tarjan numbers 3 bytes hold (all ones is DONE, 0 EMPTY).
/// A slot's number is a fifth of it for a 6-byte marking, and most state
/// spaces this tool can hold are below this.
const NUMBERS_IN_3: usize = (1 << 24) - 2;

/// The Tarjan number of an empty slot.
const EMPTY: u32 = 0;
/// The Tarjan number of a state whose component has closed.
const DONE: u32 = u32::MAX;

/// Slots past the last home a probe may run into before the table grows
/// (linear probing never wraps, so the table can double in place).
const TAIL: usize = 256;

/// Markings, each with its Tarjan number, in open addressing.
struct Table {
    /// Bytes of a marking.
    stride: usize,
    /// Bytes of a number: 3 (up to NUMBERS_IN_3 states), or 4.
    number_bytes: usize,
    /// Bytes of a slot: the marking, then its number (little-endian).
    slot: usize,
    /// Capacity − 1; the capacity is a power of two.
    mask: usize,
    /// Slots past the capacity that probes may use.
    tail: usize,
    len: usize,
    slots: Vec<u8>,
}

impl Table {
    fn new(stride: usize, number_bytes: usize) -> Table {
        // Small, so even a small net takes the table through its growth.
        let capacity = 1 << 6;
        let slot = stride + number_bytes;
        Table {
            stride,
            number_bytes,
            slot,
            mask: capacity - 1,
            tail: TAIL,
            len: 0,
            slots: vec![0; (capacity + TAIL) * slot + PAD],
        }
    }

    fn end(&self) -> usize {
        self.mask + 1 + self.tail
    }

    fn number(&self, i: usize) -> u32 {
        self.decode(&self.slots[i * self.slot + self.stride..])
    }

    /// The number whose bytes start `bytes` (4 of them readable): all ones
    /// in its width is DONE.
    fn decode(&self, bytes: &[u8]) -> u32 {
        let word = u32::from_le_bytes(bytes[..4].try_into().expect("four bytes"));
        let ones = u32::MAX >> (8 * (4 - self.number_bytes));
        match word & ones {
            n if n == ones => DONE,
            n => n,
        }
    }

    fn set_number(&mut self, i: usize, n: u32) {
        let at = i * self.slot + self.stride;
        self.slots[at..at + self.number_bytes]
            .copy_from_slice(&n.to_le_bytes()[..self.number_bytes]);
    }

    /// The hash of marking `m` (which has PAD spare bytes); its home slot
    /// is the low bits.
    fn hash(&self, m: &[u8]) -> u64 {
        let h = if self.stride <= 16 {
            let [low, high] = words(m, self.stride);
            low ^ high.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(29)
        } else {
            let mut h = FxHasher::default();
            h.write(&m[..self.stride]);
            h.finish()
        };
        // FxHash's low bits are weak.
        let h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^ (h >> 33)
    }

    /// Starts loading the home slot of `hash`, so lookups overlap.
    fn prefetch(&self, hash: u64) {
        self.prefetch_slot(hash as usize & self.mask);
    }

    /// Starts loading slot `i`.
    fn prefetch_slot(&self, i: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let at = i * self.slot;
            // SAFETY: the address lies inside the table's buffer; a
            // prefetch reads nothing into the program.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(self.slots.as_ptr().add(at).cast()) }
        }
    }

    /// Whether slot `i` holds `m`.
    fn holds(&self, i: usize, m: &[u8]) -> bool {
        let at = i * self.slot;
        if self.stride <= 16 {
            words(&self.slots[at..], self.stride) == words(m, self.stride)
        } else {
            self.slots[at..at + self.stride] == m[..self.stride]
        }
    }

    /// Whether one more marking would fill the table past 85 %, where
    /// linear probing slows: it must grow first.
    fn full(&self) -> bool {
        (self.len + 1) * 20 > (self.mask + 1) * 17
    }

    /// The slot holding `m` (whose hash is `hash`), and its number; or, if
    /// `m` is new, the slot it is now written to numbered `n`, and EMPTY.
    fn find_or_insert(&mut self, hash: u64, m: &[u8], n: u32) -> (usize, u32) {
        loop {
            let mut i = hash as usize & self.mask;
            while i < self.end() {
                let number = self.number(i);
                if number == EMPTY {
                    self.write(i, &m[..self.stride], n);
                    self.len += 1;
                    return (i, EMPTY);
                }
                if self.holds(i, m) {
                    return (i, number);
                }
                i += 1;
            }
            self.lengthen();
        }
    }

    fn write(&mut self, i: usize, m: &[u8], n: u32) {
        let at = i * self.slot;
        self.slots[at..at + self.stride].copy_from_slice(m);
        self.set_number(i, n);
    }

    /// A longer tail, for a cluster that ran off the end.
    fn lengthen(&mut self) {
        self.tail *= 2;
        self.slots.resize(self.end() * self.slot + PAD, 0);
    }

    /// Doubles the capacity in place; `open` follows the open states, each
    /// of which must be numbered by its place on it, plus one. A slot's home either stays or moves up
    /// by the old capacity; taking the old slots in order and putting each
    /// back from its new home, every probe path stays unbroken: the slots
    /// before an entry are either already final or in the new upper half,
    /// which only final entries fill. The old tail overlaps that half, so
    /// its entries are set aside first.
    fn grow(&mut self, open: &mut [u32]) {
        let old = self.mask + 1;
        let mut aside: Vec<u8> = Vec::new();
        for i in old..self.end() {
            if self.number(i) != EMPTY {
                let at = i * self.slot;
                aside.extend_from_slice(&self.slots[at..at + self.slot]);
                self.slots[at..at + self.slot].fill(0);
            }
        }
        self.mask = 2 * old - 1;
        let bytes = self.end() * self.slot + PAD;
        let kept = self.slots.len();
        self.slots.reserve_exact(bytes - kept);
        huge_pages(self.slots.as_ptr(), self.slots.capacity(), false);
        self.slots.resize(bytes, 0);
        huge_pages(self.slots.as_ptr(), kept, true);
        let mut entry = vec![0u8; self.slot + PAD];
        for i in 0..old {
            if self.number(i) != EMPTY {
                let at = i * self.slot;
                entry[..self.slot].copy_from_slice(&self.slots[at..at + self.slot]);
                self.slots[at..at + self.slot].fill(0);
                self.put_back(&entry, open);
            }
        }
        for e in aside.chunks(self.slot) {
            entry[..self.slot].copy_from_slice(e);
            self.put_back(&entry, open);
        }
    }

    /// Writes a slot's bytes (with PAD spare) to the first free slot from
    /// its home; an open state's place on Tarjan's stack follows it.
    fn put_back(&mut self, entry: &[u8], open: &mut [u32]) {
        let n = self.decode(&entry[self.stride..]);
        loop {
            let home = self.hash(entry) as usize & self.mask;
            if let Some(i) = (home..self.end()).find(|&i| self.number(i) == EMPTY) {
                self.write(i, &entry[..self.stride], n);
                if n != DONE {
                    open[n as usize - 1] = i as u32;
                }
                return;
            }
            self.lengthen();
        }
    }
}

/// Asks for `bytes` from `start` (an allocation this program owns) in
/// 2 MB pages, where the kernel leaves that to the program: each edge lands
/// on a random slot, and with 4 KB pages nearly every one also misses the
/// TLB, which stalls even a prefetch. Advice given before the memory is
/// first written makes it fault in large; `collapse` also merges pages
/// already written (the part a reallocation kept).
fn huge_pages(start: *const u8, bytes: usize, collapse: bool) {
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 4096;
        let from = (start as usize).next_multiple_of(PAGE);
        let to = (start as usize + bytes) / PAGE * PAGE;
        if to > from {
            // SAFETY: the range lies inside an allocation of this program
            // and is page-aligned; the advice changes neither its contents
            // nor its mapping, and a refusal is harmless.
            unsafe {
                libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_HUGEPAGE);
                #[cfg(target_env = "gnu")]
                if collapse {
                    libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_COLLAPSE);
                }
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (start, bytes, collapse);
}

/// Copies a marking of `stride` bytes into `to`, which has PAD spare bytes
/// (what follows the marking there may be overwritten); a short one as one
/// word, since a call to memcpy per firing costs more than the firing.
fn copy_marking(to: &mut [u8], from: &[u8], stride: usize) {
    if stride <= 8 {
        to[..8].copy_from_slice(&from[..8]);
    } else if stride <= 16 {
        to[..16].copy_from_slice(&from[..16]);
    } else {
        to[..stride].copy_from_slice(&from[..stride]);
    }
}

/// The first `stride` (≤ 16) bytes of `m` as two words, the bytes past
/// them cleared; `m` has 8 readable bytes past the marking, so 16 when the
/// second word is needed.
fn words(m: &[u8], stride: usize) -> [u64; 2] {
    let keep = |w: u64, bytes: usize| {
        if bytes >= 8 {
            w
        } else {
            w & ((1u64 << (8 * bytes)) - 1)
        }
    };
    let low = u64::from_le_bytes(m[..8].try_into().expect("eight bytes"));
    if stride <= 8 {
        return [keep(low, stride), 0];
    }
    let high = u64::from_le_bytes(m[8..16].try_into().expect("eight bytes"));
    [low, keep(high, stride - 8)]
}

/// A state on the depth-first path: its place on Tarjan's stack, which is
/// also its Tarjan number (the stack holds open states in the order they
/// were reached), with three flags in the top bits. Its low number lives in
/// the table, in place of its own (Pearce's variant of Tarjan's algorithm),
/// so a frame is 4 bytes: on a strongly connected graph the path grows as
/// long as the graph is large.
#[derive(Clone, Copy)]
struct Frame(u32);

/// The state fired something.
const FIRED: u32 = 1 << 31;
/// An edge from the state, or from its component below it, leaves the component.
const EXITS: u32 = 1 << 30;
/// The state reaches a state reached before it: it is not its component's root.
const BELOW: u32 = 1 << 29;

impl Frame {
    fn at(self) -> u32 {
        self.0 & !(FIRED | EXITS | BELOW)
    }

    fn has(self, flag: u32) -> bool {
        self.0 & flag != 0
    }
}

/// The transitions each frame on the path has still to fire, the top
/// frame's last, and the transition that reached each frame.
///
/// A net of at most 64 transitions keeps a bit mask per frame (2 bytes for
/// Kanban's 16), and leaves the bit of the transition it descends by set
/// until the child returns: the lowest bit then names the tree edge. A
/// larger net keeps a list of labels per frame, begun by a separator (the
/// transition count), and the tree edges in a list of their own.
enum Pending {
    Masks {
        bytes: usize,
        masks: Vec<u8>,
    },
    Lists {
        separator: u32,
        labels: Labels,
        by: Labels,
    },
}

impl Pending {
    fn new(transitions: usize) -> Pending {
        if transitions <= 64 {
            Pending::Masks {
                bytes: transitions.div_ceil(8).max(1),
                masks: Vec::new(),
            }
        } else {
            Pending::Lists {
                separator: transitions as u32,
                labels: Labels::for_transitions(transitions + 1),
                by: Labels::for_transitions(transitions),
            }
        }
    }

    /// A frame with `enabled` (in transition order) to fire.
    fn push(&mut self, enabled: &[u32]) {
        match self {
            Pending::Masks { bytes, masks } => {
                let mask = enabled.iter().fold(0u64, |m, &t| m | 1 << t);
                masks.extend_from_slice(&mask.to_le_bytes()[..*bytes]);
            }
            Pending::Lists {
                separator, labels, ..
            } => {
                labels.push(*separator);
                for &t in enabled.iter().rev() {
                    labels.push(t);
                }
            }
        }
    }

    fn top_mask(bytes: usize, masks: &[u8]) -> u64 {
        let mut word = [0u8; 8];
        word[..bytes].copy_from_slice(&masks[masks.len() - bytes..]);
        u64::from_le_bytes(word)
    }

    fn set_top_mask(bytes: usize, masks: &mut [u8], mask: u64) {
        let at = masks.len() - bytes;
        masks[at..].copy_from_slice(&mask.to_le_bytes()[..bytes]);
    }

    /// The top frame's next transitions, up to `out.len()` of them, and
    /// whether these are all it has left.
    fn peek(&self, out: &mut [u32]) -> (usize, bool) {
        match self {
            Pending::Masks { bytes, masks } => {
                let mut mask = Pending::top_mask(*bytes, masks);
                let mut n = 0;
                while mask != 0 && n < out.len() {
                    out[n] = mask.trailing_zeros();
                    mask &= mask - 1;
                    n += 1;
                }
                (n, mask == 0)
            }
            Pending::Lists {
                separator, labels, ..
            } => {
                let end = labels.len();
                let mut n = 0;
                while n < out.len() && labels.get(end - 1 - n) != *separator {
                    out[n] = labels.get(end - 1 - n);
                    n += 1;
                }
                (n, labels.get(end - 1 - n) == *separator)
            }
        }
    }

    /// The top frame's next transition has been fired without descending.
    fn take(&mut self) {
        match self {
            Pending::Masks { bytes, masks } => {
                let mask = Pending::top_mask(*bytes, masks);
                Pending::set_top_mask(*bytes, masks, mask & mask.wrapping_sub(1));
            }
            Pending::Lists { labels, .. } => labels.truncate(labels.len() - 1),
        }
    }

    /// The top frame's next transition, `t`, reached a new state, whose
    /// frame comes next.
    fn descend(&mut self, t: u32) {
        if let Pending::Lists { labels, by, .. } = self {
            labels.truncate(labels.len() - 1);
            by.push(t);
        }
    }

    /// Removes the top frame, which has nothing left; with a parent below,
    /// the transition that reached it.
    fn pop(&mut self) -> Option<u32> {
        match self {
            Pending::Masks { bytes, masks } => {
                masks.truncate(masks.len() - *bytes);
                if masks.is_empty() {
                    return None;
                }
                let mask = Pending::top_mask(*bytes, masks);
                Pending::set_top_mask(*bytes, masks, mask & mask.wrapping_sub(1));
                Some(mask.trailing_zeros())
            }
            Pending::Lists { labels, by, .. } => {
                labels.truncate(labels.len() - 1);
                let t = by.len().checked_sub(1).map(|last| by.get(last));
                by.truncate(by.len().saturating_sub(1));
                t
            }
        }
    }
}

/// Successors looked up together, so their cache misses overlap.
const BATCH: usize = 16;

struct Search<'a> {
    layout: &'a Layout,
    compiled: &'a [Compiled],
    at_limit: &'a mut [bool],
    stride: usize,
    table: Table,
    candidates: Candidates,
    frames: Vec<Frame>,
    pending: Pending,
    /// Tarjan's stack: the slots of states whose component is still open.
    open: Vec<u32>,
    current: Vec<u32>,
    enabled: Vec<u32>,
    bounds: Bounds,
    states: usize,
    edges: usize,
    dead: bool,
    components: usize,
    /// Per transition: it fires; it fires inside a component.
    fires: Vec<bool>,
    cycles: Vec<bool>,
    /// Terminal components, and for each transition how many it fires in.
    terminals: usize,
    in_terminals: Vec<usize>,
    /// The last terminal component each transition was counted for.
    seen_in: Vec<usize>,
    /// States 3-byte numbers count here (NUMBERS_IN_3 but in a test).
    numbers_in_3: usize,
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
            table: Table::new(stride, number_bytes),
            candidates: Candidates::new(compiled, places),
            frames: Vec::new(),
            pending: Pending::new(transitions),
            open: Vec::new(),
            current: vec![0; places],
            enabled: Vec::with_capacity(transitions),
            bounds: Bounds::new(places),
            states: 0,
            edges: 0,
            dead: false,
            components: 0,
            fires: vec![false; transitions],
            cycles: vec![false; transitions],
            terminals: 0,
            in_terminals: vec![0; transitions],
            seen_in: vec![usize::MAX; transitions],
            numbers_in_3: NUMBERS_IN_3,
        }
    }

    /// Grows the table when it is full. Growth moves open states, and the
    /// stack follows each through its number, so for the while each is
    /// numbered by its place on the stack, its low number set aside.
    fn make_room(&mut self) {
        if !self.table.full() {
            return;
        }
        let lows: Vec<u32> = (0..self.open.len())
            .map(|k| {
                let slot = self.open[k] as usize;
                let low = self.table.number(slot);
                self.table.set_number(slot, k as u32 + 1);
                low
            })
            .collect();
        self.table.grow(&mut self.open);
        for (&slot, &low) in self.open.iter().zip(&lows) {
            self.table.set_number(slot as usize, low);
        }
    }

    /// The marking in slot `slot`, into `out` (which has PAD spare bytes).
    fn marking(&self, slot: u32, out: &mut [u8]) {
        let at = slot as usize * self.table.slot;
        copy_marking(out, &self.table.slots[at..], self.stride);
    }

    fn run(mut self, initial: &[u32], options: &mut Options) -> Result<Reading, Stop> {
        let started = Instant::now();
        let stride = self.stride;
        let mut packed = vec![0u8; stride + PAD];
        // The batch's successors, their hashes, and whether each is an edge.
        let mut batch = vec![0u8; BATCH * stride + PAD];
        let mut hashes = [0u64; BATCH];
        let mut edge = [false; BATCH];
        for (p, &v) in initial.iter().enumerate() {
            self.layout.set(&mut batch, p, v);
        }
        let hash = self.table.hash(&batch);
        let (slot, _) = self.table.find_or_insert(hash, &batch, 1);
        self.enter(slot, &batch[..stride + PAD]);
        let mut firing = [0u32; BATCH];
        while let Some(&top) = self.frames.last() {
            let (n, last) = self.pending.peek(&mut firing);
            if n == 0 {
                self.leave();
                continue;
            }
            let top_slot = self.open[top.at() as usize];
            self.marking(top_slot, &mut packed);
            if last && let Some(parent) = self.frames.len().checked_sub(2) {
                // The parent's marking is read again when this state is left.
                let slot = self.open[self.frames[parent].at() as usize];
                self.table.prefetch_slot(slot as usize);
            }
            let layout = self.layout;
            for j in 0..n {
                let t = firing[j] as usize;
                let next = &mut batch[j * stride..(j + 1) * stride + PAD];
                copy_marking(next, &packed, stride);
                edge[j] = match fire(
                    layout,
                    &self.compiled[t],
                    |p| layout.count(&packed, p),
                    next,
                    self.at_limit,
                ) {
                    Fired::Next => true,
                    Fired::Blocked => false,
                    Fired::Overflow => return Err(Stop::Overflow),
                    Fired::Outgrown { p, v } => return Err(Stop::Widen { p, v }),
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
                self.frames.last_mut().expect("a frame is open").0 |= FIRED;
                self.edges += 1;
                self.fires[t as usize] = true;
                self.make_room();
                let fresh = self.open.len() as u32 + 1;
                let next = &batch[j * stride..(j + 1) * stride + PAD];
                let (slot, number) = self.table.find_or_insert(hashes[j], next, fresh);
                match number {
                    EMPTY => {
                        if self.states >= options.max_states {
                            return Err(Stop::Limit);
                        }
                        if self.table.number_bytes == 3 && self.states >= self.numbers_in_3 {
                            return Err(Stop::Renumber);
                        }
                        self.pending.descend(t);
                        self.enter(slot, next);
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
                    DONE => {
                        self.pending.take();
                        self.frames.last_mut().expect("a frame is open").0 |= EXITS;
                    }
                    low => {
                        self.pending.take();
                        // An edge back into the open part: the top state
                        // reaches as low as the target does.
                        let top_slot = self.open[top.at() as usize] as usize;
                        if low < self.table.number(top_slot) {
                            self.table.set_number(top_slot, low);
                            self.frames.last_mut().expect("a frame is open").0 |= BELOW;
                        }
                        self.cycles[t as usize] = true;
                    }
                }
            }
        }
        let transitions = self.compiled.len();
        let liveness = (0..transitions)
            .map(|t| {
                if self.terminals > 0 && self.in_terminals[t] == self.terminals {
                    Liveness::L4
                } else if self.cycles[t] {
                    Liveness::L3
                } else if self.fires[t] {
                    Liveness::L1
                } else {
                    Liveness::L0
                }
            })
            .collect();
        Ok(Reading {
            states: self.states,
            edges: self.edges,
            bounds: self.bounds,
            dead: self.dead,
            components: self.components,
            liveness,
            bytes_per_marking: self.layout.stride,
        })
    }

    /// Puts the state `m` (just written to `slot`, numbered by its place
    /// on Tarjan's stack) on the path and on that stack, with its enabled
    /// transitions.
    fn enter(&mut self, slot: usize, m: &[u8]) {
        let at = self.open.len() as u32;
        self.open.push(slot as u32);
        self.layout.unpack(m, &mut self.current);
        self.bounds.take(&self.current);
        self.enabled.clear();
        self.candidates
            .enabled(self.compiled, &self.current, &mut self.enabled);
        self.pending.push(&self.enabled);
        self.frames.push(Frame(at));
        self.states += 1;
    }

    /// Ends the search from the top frame: closes its component if it is
    /// the component's root, and tells its parent what the tree edge was.
    fn leave(&mut self) {
        let v = self.frames.pop().expect("a frame is open");
        let by = self.pending.pop();
        self.dead |= !v.has(FIRED);
        let at = v.at() as usize;
        let root = !v.has(BELOW);
        if root {
            if !v.has(EXITS) {
                self.count_terminal(at);
            }
            for &slot in &self.open[at..] {
                self.table.set_number(slot as usize, DONE);
            }
            self.open.truncate(at);
            self.components += 1;
        }
        let (Some(&parent), Some(by)) = (self.frames.last(), by) else {
            return;
        };
        let by = by as usize;
        let mut flags = 0;
        if root {
            flags |= EXITS;
        } else {
            // The tree edge stays inside the component, and the parent
            // reaches as low as v does.
            self.cycles[by] = true;
            if v.has(EXITS) {
                flags |= EXITS;
            }
            let low = self.table.number(self.open[at] as usize);
            let parent_slot = self.open[parent.at() as usize] as usize;
            if low < self.table.number(parent_slot) {
                self.table.set_number(parent_slot, low);
                flags |= BELOW;
            }
        }
        self.frames.last_mut().expect("the parent is open").0 |= flags;
    }

    /// Counts the component of open states from `from` on, which no edge
    /// leaves, for every transition that fires inside it.
    fn count_terminal(&mut self, from: usize) {
        let stride = self.stride;
        let mut member = vec![0u8; stride + PAD];
        let mut next = vec![0u8; stride + PAD];
        for k in from..self.open.len() {
            self.marking(self.open[k], &mut member);
            self.layout.unpack(&member, &mut self.current);
            self.enabled.clear();
            self.candidates
                .enabled(self.compiled, &self.current, &mut self.enabled);
            for &t in &self.enabled {
                let t = t as usize;
                if self.seen_in[t] == self.terminals {
                    continue;
                }
                next.copy_from_slice(&member);
                let current = &self.current;
                if let Fired::Next = fire(
                    self.layout,
                    &self.compiled[t],
                    |p| current[p],
                    &mut next,
                    self.at_limit,
                ) {
                    self.seen_in[t] = self.terminals;
                    self.in_terminals[t] += 1;
                }
            }
        }
        self.terminals += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state space larger than 3-byte numbers count is searched again
    /// with 4: here with the count lowered to 100, on a ring of 300 states.
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
        let layout = initial_layout(&net);
        let initial = net.initial_marking();
        let mut at_limit = vec![false; net.places.len()];
        let search = |bytes, at_limit: &mut [bool]| {
            let mut search = Search::new(&layout, &compiled, at_limit, bytes);
            search.numbers_in_3 = 100;
            search.run(&initial.0, &mut Options::default())
        };
        assert!(matches!(search(3, &mut at_limit), Err(Stop::Renumber)));
        let reading = search(4, &mut at_limit)
            .ok()
            .expect("4 bytes number them all");
        assert_eq!((reading.states, reading.components), (300, 1));
    }

    /// Markings of `stride` bytes from a counter, spread over every byte:
    /// distinct counters give distinct markings (an odd multiplier permutes
    /// the low bytes).
    fn marking(k: u64, stride: usize) -> Vec<u8> {
        let x = k.wrapping_mul(0x9e37_79b9_7f4a_7c15).to_le_bytes();
        let mut m = vec![0u8; stride + PAD];
        for (i, b) in m.iter_mut().take(stride).enumerate() {
            *b = x[i % 8] ^ (i / 8) as u8;
        }
        m
    }

    /// Through many doublings, every marking stays found under its own
    /// number, a second insertion finds it, and the slots Tarjan's stack
    /// holds follow their states.
    #[test]
    fn the_table_keeps_every_marking_and_its_slot_through_growth() {
        for (stride, number_bytes) in [(1, 3), (3, 4), (8, 3), (13, 4), (20, 3)] {
            let mut table = Table::new(stride, number_bytes);
            let mut open: Vec<u32> = Vec::new();
            let mut numbers = Vec::new();
            let count = if stride == 1 { 256 } else { 60_000 };
            let mut distinct = std::collections::HashSet::new();
            for k in 0..count as u64 {
                let m = marking(k, stride);
                if !distinct.insert(m[..stride].to_vec()) {
                    continue;
                }
                // Every third state stays open; the rest are done.
                let n = if k % 3 == 0 {
                    open.len() as u32 + 1
                } else {
                    DONE
                };
                if table.full() {
                    table.grow(&mut open);
                }
                let (slot, before) = table.find_or_insert(table.hash(&m), &m, n);
                assert_eq!(before, EMPTY, "stride {stride}: marking {k} is new");
                if n != DONE {
                    open.push(slot as u32);
                }
                numbers.push((m, n));
            }
            assert!(table.mask + 1 > 64, "the table grew");
            for (m, n) in &numbers {
                let (slot, found) = table.find_or_insert(table.hash(m), m, 7);
                assert_eq!(found, *n, "stride {stride}: found under its number");
                assert_eq!(&table.slots[slot * table.slot..][..stride], &m[..stride]);
                if *n != DONE {
                    assert_eq!(open[*n as usize - 1] as usize, slot, "its slot followed it");
                }
            }
            assert_eq!(table.len, numbers.len());
        }
    }
}
