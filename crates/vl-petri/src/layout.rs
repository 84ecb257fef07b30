//! How a marking is packed into bytes, and a net compiled for firing on
//! packed markings: what the explorer (`explore`), the threaded counter
//! (`frontier`) and the on-the-fly reader (`onthefly`) share.

use crate::net::{Marking, Net};

/// Where each place's count sits in a packed marking.
///
/// A place has a field of its own, just wide enough for its count; or it
/// belongs to a one-hot group, places a P-invariant proves always hold one
/// token between them (a process's local states, a resource's holders),
/// which share one field naming the marked member: ⌈log₂ k⌉ bits for k
/// places instead of k.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    /// Bit offset of each place's field (a member's is its group's).
    offset: Vec<u32>,
    /// Bits of each place's field (0 for a place that is provably always empty).
    width: Vec<u8>,
    /// For a group member, its number in the group: the field's value when
    /// it holds the token.
    member: Vec<Option<u32>>,
    /// The one-hot groups, as lists of places.
    groups: Vec<Vec<usize>>,
    /// The places with fields of their own.
    own: Vec<usize>,
    /// Places given no field because the others determine them (see
    /// [`search_layout`]): a search that carries each marking's counts
    /// along its path never needs them unpacked.
    derived: Vec<bool>,
    /// Bytes per marking.
    pub(crate) stride: usize,
}

/// Bytes of slack after a packed marking, so a place is read and written as
/// one unaligned 8-byte word.
pub(crate) const PAD: usize = 8;

impl Layout {
    /// Places get fields of `width` bits in order, except members of
    /// `groups`, whose group's field comes where its first member is.
    fn new(mut width: Vec<u8>, groups: Vec<Vec<usize>>, derived: Vec<bool>) -> Layout {
        for (w, &d) in width.iter_mut().zip(&derived) {
            if d {
                *w = 0;
            }
        }
        let mut member = vec![None; width.len()];
        let mut first_of = vec![None; width.len()];
        for (g, places) in groups.iter().enumerate() {
            let field = bits(places.len() as u32 - 1);
            for (i, &p) in places.iter().enumerate() {
                member[p] = Some(i as u32);
                width[p] = field;
            }
            first_of[places[0]] = Some(g);
        }
        let mut offset = vec![0u32; width.len()];
        let mut bits = 0u32;
        for p in 0..width.len() {
            match (member[p], first_of[p]) {
                (None, _) => {
                    offset[p] = bits;
                    bits += u32::from(width[p]);
                }
                (Some(_), Some(g)) => {
                    for &q in &groups[g] {
                        offset[q] = bits;
                    }
                    bits += u32::from(width[p]);
                }
                (Some(_), None) => {}
            }
        }
        Layout {
            offset,
            width,
            own: (0..member.len()).filter(|&p| member[p].is_none()).collect(),
            member,
            groups,
            derived,
            stride: bits.div_ceil(8) as usize,
        }
    }

    /// The same layout with place `p` wide enough for `v`, and every place
    /// in `also` (which reached its own limit) likewise doubled, so places
    /// that grow together are repacked together. Group members never grow.
    pub(crate) fn widened(&self, p: usize, v: u32, also: &[bool]) -> Layout {
        let mut width = self.width.clone();
        for (q, w) in width.iter_mut().enumerate() {
            if (q == p || also[q]) && self.member[q].is_none() {
                *w = ((*w).max(1) * 2).min(32);
            }
        }
        width[p] = width[p].max(bits(v));
        Layout::new(width, self.groups.clone(), self.derived.clone())
    }

    /// The runs that repack a marking from this layout into `wider`, the
    /// same one with some fields widened: a few runs instead of a field
    /// at a time.
    fn runs_to(&self, wider: &Layout) -> Vec<FieldRun> {
        let mut fields: Vec<usize> = self.own.clone();
        fields.extend(self.groups.iter().map(|places| places[0]));
        fields.retain(|&p| self.width[p] > 0);
        fields.sort_by_key(|&p| self.offset[p]);
        let mut runs: Vec<FieldRun> = Vec::new();
        for p in fields {
            let (from, to, bits) = (self.offset[p], wider.offset[p], u32::from(self.width[p]));
            match runs.last_mut() {
                Some(run) if run.from + run.bits == from && run.to + run.bits == to => {
                    run.bits += bits;
                }
                _ => runs.push(FieldRun { from, to, bits }),
            }
        }
        runs
    }

    /// The largest count place `p` can hold.
    pub(crate) fn max(&self, p: usize) -> u32 {
        match (self.member[p], self.width[p]) {
            (Some(_), _) => 1,
            (None, 32..) => u32::MAX,
            (None, w) => (1u32 << w) - 1,
        }
    }

    /// The bits of place `p`'s field (its group's, for a member).
    fn field(&self, packed: &[u8], p: usize) -> u32 {
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

    /// The number of places laid out.
    pub(crate) fn places(&self) -> usize {
        self.width.len()
    }

    /// Writes `v` (which fits) into place `p` of `packed`, which has PAD
    /// spare bytes. A group member taking the token names itself in the
    /// group's field; one losing it writes nothing, since another member
    /// takes the token in the same firing.
    pub(crate) fn set(&self, packed: &mut [u8], p: usize, v: u32) {
        let v = match self.member[p] {
            Some(i) if v == 1 => i,
            Some(_) => return,
            // A place with no field: always empty, or derived.
            None if self.width[p] == 0 => return,
            None => v,
        };
        let bit = self.offset[p] as usize;
        let at = bit / 8;
        let mut word = [0u8; 8];
        word.copy_from_slice(&packed[at..at + 8]);
        let mask = ((1u64 << self.width[p]) - 1) << (bit % 8);
        let w = (u64::from_le_bytes(word) & !mask) | (u64::from(v) << (bit % 8));
        packed[at..at + 8].copy_from_slice(&w.to_le_bytes());
    }

    /// Writes each place's count in `counts` into `packed` (zeroed, with
    /// PAD spare bytes).
    pub(crate) fn pack(&self, counts: &[u32], packed: &mut [u8]) {
        for (p, &v) in counts.iter().enumerate() {
            self.set(packed, p, v);
        }
    }

    pub(crate) fn unpack(&self, packed: &[u8], out: &mut [u32]) {
        debug_assert!(
            !self.derived.contains(&true),
            "derived places cannot be unpacked"
        );
        for &p in &self.own {
            out[p] = self.field(packed, p);
        }
        for places in &self.groups {
            for &q in places {
                out[q] = 0;
            }
            out[places[self.field(packed, places[0]) as usize]] = 1;
        }
    }
}

/// A transition compiled for fast firing.
pub(crate) struct Compiled {
    /// (place, weight) that must be present.
    need: Vec<(u32, u32)>,
    /// (place, weight): enabled only while the place holds fewer.
    inhibit: Vec<(u32, u32)>,
    /// (place, change) when it fires, with its capacity if any.
    delta: Vec<(u32, i64, Option<u32>)>,
}

impl Compiled {
    /// (place, change, capacity) of each place firing changes.
    pub(crate) fn changes(&self) -> &[(u32, i64, Option<u32>)] {
        &self.delta
    }

    /// Whether the input and inhibitor arcs allow firing, given each
    /// place's count (capacities are checked as it fires).
    pub(crate) fn allows(&self, count: impl Fn(usize) -> u32) -> bool {
        self.need.iter().all(|&(p, w)| count(p as usize) >= w)
            && self.inhibit.iter().all(|&(p, w)| count(p as usize) < w)
    }
}

pub(crate) fn compile(net: &Net) -> Vec<Compiled> {
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

/// Which transitions a marking can enable. A net with few transitions
/// tries them all; in a larger one each is listed under its first input
/// place, so only those under a marked place (and those with no input) are
/// tried.
pub(crate) struct Candidates {
    listed_under: Vec<Vec<u32>>,
    always: Vec<u32>,
    all: bool,
}

/// Transitions a net may have for trying them all to cost less than
/// gathering the lists of the marked places.
const TRY_ALL: usize = 64;

impl Candidates {
    pub(crate) fn new(compiled: &[Compiled], places: usize) -> Candidates {
        let mut listed_under: Vec<Vec<u32>> = vec![Vec::new(); places];
        let mut always: Vec<u32> = Vec::new();
        for (t, tr) in compiled.iter().enumerate() {
            match tr.need.first() {
                Some(&(p, _)) => listed_under[p as usize].push(t as u32),
                None => always.push(t as u32),
            }
        }
        Candidates {
            listed_under,
            always,
            all: compiled.len() <= TRY_ALL,
        }
    }

    /// Appends to `out` the transitions whose input and inhibitor arcs
    /// allow them at `current`, in transition order (so the numbering of
    /// states does not depend on this filter). Capacities are checked as
    /// each fires.
    pub(crate) fn enabled(&self, compiled: &[Compiled], current: &[u32], out: &mut Vec<u32>) {
        let allows = |t: u32| compiled[t as usize].allows(|p| current[p]);
        if self.all {
            out.extend((0..compiled.len() as u32).filter(|&t| allows(t)));
            return;
        }
        let from = out.len();
        out.extend(self.always.iter().copied().filter(|&t| allows(t)));
        for (p, &v) in current.iter().enumerate() {
            if v > 0 {
                out.extend(self.listed_under[p].iter().copied().filter(|&t| allows(t)));
            }
        }
        out[from..].sort_unstable();
    }
}

/// What firing an enabled transition gave.
pub(crate) enum Firing {
    /// The successor is written.
    Next,
    /// A capacity forbids it: no edge.
    Blocked,
    /// Place `p` would hold `v`, more than its field holds.
    Outgrown { p: usize, v: u32 },
    /// A place would hold more than any field can.
    Overflow,
}

/// Writes into `next` (a copy of the marking, packed, with PAD spare bytes)
/// the marking firing `tr` gives, given each place's count. Places that
/// reach the most their field holds are marked in `at_limit`, so a later
/// widening widens them too.
pub(crate) fn fire(
    layout: &Layout,
    tr: &Compiled,
    count: impl Fn(usize) -> u32,
    next: &mut [u8],
    at_limit: &mut [bool],
) -> Firing {
    for &(p, change, capacity) in &tr.delta {
        let p = p as usize;
        let v = i64::from(count(p)) + change;
        if capacity.is_some_and(|cap| v > i64::from(cap)) {
            return Firing::Blocked;
        }
        if layout.derived[p] {
            continue;
        }
        let max = i64::from(layout.max(p));
        if v == max {
            at_limit[p] = true;
        }
        if v > max {
            return match u32::try_from(v) {
                Ok(v) if layout.width[p] < 32 => Firing::Outgrown { p, v },
                _ => Firing::Overflow,
            };
        }
        layout.set(next, p, v as u32);
    }
    Firing::Next
}

/// Rows the invariant computation may use while looking for place bounds,
/// and the memory it may take.
const BOUND_ROWS: usize = 5_000;
const BOUND_BYTES: usize = 16 << 20;

/// Bits needed to write `v`.
fn bits(v: u32) -> u8 {
    (32 - v.leading_zeros()) as u8
}

/// The places some firing sequence might mark: a fixpoint from the marked
/// ones over the transitions whose inputs all might be marked, blind to
/// weights, inhibitor arcs and capacities, so it can only say too much. A
/// place it leaves out stays empty forever and needs no bits, which the
/// invariants also show but cannot always be computed in time to.
fn markable(net: &Net, initial: &Marking) -> Vec<bool> {
    let mut marked: Vec<bool> = initial.0.iter().map(|&m| m > 0).collect();
    let mut grew = true;
    while grew {
        grew = false;
        for t in &net.transitions {
            if t.pre.iter().all(|a| marked[a.place.0]) {
                for a in &t.post {
                    grew |= !marked[a.place.0];
                    marked[a.place.0] = true;
                }
            }
        }
    }
    marked
}

/// The layout the minimal P-invariants allow: y·m = y·m0 for every
/// reachable m, so m(p) ≤ y·m0 / y(p) for every invariant y covering p;
/// and an invariant of unit weights holding one token makes its places a
/// one-hot group (disjoint groups, largest first). A place no invariant
/// bounds starts as wide as its initial count and widens when outgrown.
pub(crate) fn initial_layout(net: &Net) -> Layout {
    let (width, groups, _) = fields(net);
    let derived = vec![false; width.len()];
    Layout::new(width, groups, derived)
}

/// The layout of [`initial_layout`] less every place the others determine,
/// for a search that carries each marking's counts along its path.
///
/// A reachable marking is m0 + C·σ, so a place whose row of the incidence
/// matrix C is a combination of other places' rows has its count fixed by
/// theirs (a P-flow, not necessarily positive, says how), and two
/// markings that differ differ in a place that keeps its field. Which
/// places keep one is a basis of C's rows chosen cheapest first: group
/// members (their group's field is shared, so they always keep it), then
/// by the bits their field takes, places no invariant bounds last, since
/// their fields would have to grow.
pub(crate) fn search_layout(net: &Net) -> Layout {
    let (width, groups, bounded) = fields(net);
    let places = width.len();
    let mut grouped = vec![false; places];
    for &p in groups.iter().flatten() {
        grouped[p] = true;
    }
    let cost = |p: usize| match (grouped[p], bounded[p]) {
        (true, _) => 0,
        (false, true) => 1 + u32::from(width[p]),
        (false, false) => 1 + 32,
    };
    let mut order: Vec<usize> = (0..places).collect();
    order.sort_by_key(|&p| cost(p));
    let derived = if places.saturating_mul(net.transitions.len()) <= DERIVE_CELLS {
        let kept = crate::linalg::basis_rows(&net.incidence(), &order);
        (0..places).map(|p| !kept[p] && !grouped[p]).collect()
    } else {
        vec![false; places]
    };
    Layout::new(width, groups, derived)
}

/// Incidence matrices larger than this many cells are not searched for
/// derived places: the elimination would cost more than it saves.
const DERIVE_CELLS: usize = 4_000_000;

/// Each place's field width, the one-hot groups, and whether an invariant
/// bounds each place (its width is then final).
fn fields(net: &Net) -> (Vec<u8>, Vec<Vec<usize>>, Vec<bool>) {
    let initial = net.initial_marking();
    let mut bounds: Vec<Option<u32>> = markable(net, &initial)
        .into_iter()
        .map(|m| (!m).then_some(0))
        .collect();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let rows = BOUND_ROWS.min(crate::invariants::p_rows_within(net, BOUND_BYTES));
    if let Ok(invariants) = crate::invariants::p_invariants(net, rows) {
        for y in &invariants {
            let total: u64 = y.iter().map(|&(p, k)| k * u64::from(initial.0[p])).sum();
            for &(p, k) in y {
                let b = u32::try_from(total / k).unwrap_or(u32::MAX);
                bounds[p] = Some(bounds[p].map_or(b, |old: u32| old.min(b)));
            }
            if total == 1 && y.len() >= 2 && y.iter().all(|&(_, k)| k == 1) {
                groups.push(y.iter().map(|&(p, _)| p).collect());
            }
        }
    }
    groups.sort_by_key(|g| std::cmp::Reverse(g.len()));
    let mut grouped = vec![false; net.places.len()];
    groups.retain(|g| {
        let free = g.iter().all(|&p| !grouped[p]);
        if free {
            g.iter().for_each(|&p| grouped[p] = true);
        }
        free
    });
    let width = bounds
        .iter()
        .zip(&initial.0)
        .map(|(bound, &m)| bound.map_or(bits(m).max(1), bits))
        .collect();
    let bounded = bounds.iter().map(Option::is_some).collect();
    (width, groups, bounded)
}

/// Repacks the markings of `store` from layout `from` into the wider `to`
/// in place: from the last state back, each state's new place lies at or
/// after its old one and before any later state's, so nothing unread is
/// overwritten and the store is never held twice.
pub(crate) fn repack(from: &Layout, to: &Layout, store: &mut Vec<u8>) {
    debug_assert!(to.stride >= from.stride, "a layout only widens");
    let states = store.len().checked_div(from.stride).unwrap_or(0);
    store.resize(states * to.stride + PAD, 0);
    let runs = from.runs_to(to);
    let mut old = vec![0u8; from.stride + PAD];
    for s in (0..states).rev() {
        old[..from.stride].copy_from_slice(&store[s * from.stride..(s + 1) * from.stride]);
        store[s * to.stride..(s + 1) * to.stride].fill(0);
        for run in &runs {
            run.copy(&old, &mut store[s * to.stride..]);
        }
    }
    store.truncate(states * to.stride);
}

/// Bits a marking keeps in one piece when its layout widens: fields that
/// lie side by side, at the same widths, in both layouts. A widened field
/// ends a run, and its count is copied into the low bits of its wider field.
struct FieldRun {
    from: u32,
    to: u32,
    bits: u32,
}

impl FieldRun {
    /// Copies the run from `old` into the zeroed `new`, both padded with
    /// PAD spare bytes, at most 56 bits at a time so that a shifted piece
    /// fits one 8-byte word.
    fn copy(&self, old: &[u8], new: &mut [u8]) {
        let mut done = 0;
        while done < self.bits {
            let n = (self.bits - done).min(56);
            let (f, t) = ((self.from + done) as usize, (self.to + done) as usize);
            let word = u64::from_le_bytes(old[f / 8..f / 8 + 8].try_into().expect("eight bytes"));
            let piece = (word >> (f % 8)) & ((1u64 << n) - 1);
            let at = &mut new[t / 8..t / 8 + 8];
            let w =
                u64::from_le_bytes((&*at).try_into().expect("eight bytes")) | (piece << (t % 8));
            at.copy_from_slice(&w.to_le_bytes());
            done += n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Places in one-hot groups of three from `grouped` on, the others of
    /// the given widths; each widened by its own amount (members never).
    fn layouts(widths: &[u8], grouped: usize, more: &[u8]) -> (Layout, Layout) {
        let groups: Vec<Vec<usize>> = (grouped..widths.len())
            .step_by(3)
            .map(|g| (g..(g + 3).min(widths.len())).collect())
            .collect();
        let derived = vec![false; widths.len()];
        let wider: Vec<u8> = (0..widths.len())
            .map(|p| (widths[p] + if p < grouped { more[p] } else { 0 }).min(32))
            .collect();
        (
            Layout::new(widths.to_vec(), groups.clone(), derived.clone()),
            Layout::new(wider, groups, derived),
        )
    }

    proptest! {
        /// Repacking into a wider layout keeps every count of every marking.
        #[test]
        fn repack_keeps_every_count(
            widths in prop::collection::vec(0u8..=32, 1..40),
            grouped_at in 0.0f64..=1.0,
            more in prop::collection::vec(0u8..=20, 40),
            seeds in prop::collection::vec(any::<u64>(), 1..6),
        ) {
            let grouped = (widths.len() as f64 * grouped_at) as usize;
            let (from, to) = layouts(&widths, grouped, &more);
            // A layout of no bits has one marking and never widens: none
            // of its places can be marked.
            prop_assume!(from.stride > 0);
            let marking = |seed: u64| -> Vec<u32> {
                let mut counts = vec![0u32; widths.len()];
                for &p in &from.own {
                    let max = u64::from(from.max(p));
                    counts[p] = if from.width[p] == 0 { 0 } else { (seed.rotate_left(p as u32 * 7) % (max + 1)) as u32 };
                }
                for places in &from.groups {
                    counts[places[seed as usize % places.len()]] = 1;
                }
                counts
            };
            let mut store = Vec::new();
            for &seed in &seeds {
                let mut packed = vec![0u8; from.stride + PAD];
                from.pack(&marking(seed), &mut packed);
                store.extend_from_slice(&packed[..from.stride]);
            }
            repack(&from, &to, &mut store);
            prop_assert_eq!(store.len(), seeds.len() * to.stride);
            for (i, &seed) in seeds.iter().enumerate() {
                let mut packed = store[i * to.stride..(i + 1) * to.stride].to_vec();
                packed.resize(to.stride + PAD, 0);
                let mut counts = vec![0u32; widths.len()];
                to.unpack(&packed, &mut counts);
                prop_assert_eq!(counts, marking(seed), "marking {}", i);
            }
        }
    }
}
