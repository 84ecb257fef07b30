//! A table of markings: open addressing over markings packed with their
//! numbers, grown in place.

use std::hash::Hasher;

use rustc_hash::FxHasher;

use super::pages::Pages;
use crate::layout::PAD;

/// The number of an empty slot; states are numbered from 1.
pub(crate) const EMPTY: u32 = 0;

/// Slots past the last home a probe may run into before the table grows
/// (linear probing never wraps, so the table can grow in place).
const TAIL: usize = 256;

/// Tables of fewer slots double; larger ones take turns growing by a half
/// and by a third, from 2ᵏ to 1.5·2ᵏ to 2ᵏ⁺¹ slots: the table is most of
/// the memory, and a doubling can leave it half empty.
const DOUBLE_BELOW: usize = 1 << 16;

/// Markings, each with a number (the order the search reached it in, or
/// just 1 for a search that only counts), in open addressing. A marking's
/// home slot is its hash scaled to the capacity (the high bits, so the
/// capacity need not be a power of two, and homes keep their order as the
/// table grows).
pub(crate) struct MarkingTable {
    /// Bytes of a marking.
    stride: usize,
    /// Bytes of a number: 1 to 4.
    pub(crate) number_bytes: usize,
    /// Bytes of a slot: the marking, then its number (little-endian).
    slot: usize,
    capacity: usize,
    /// Slots past the capacity that probes may use.
    tail: usize,
    len: usize,
    slots: Pages,
}

impl MarkingTable {
    pub(crate) fn new(stride: usize, number_bytes: usize) -> MarkingTable {
        // Small, so even a small net takes the table through its growth.
        MarkingTable::with_room(stride, number_bytes, 0)
    }

    /// A table that takes `markings` before it first grows.
    pub(crate) fn with_room(stride: usize, number_bytes: usize, markings: usize) -> MarkingTable {
        let capacity = (markings * 20 / 17 + 1).max(1 << 6);
        let slot = stride + number_bytes;
        MarkingTable {
            stride,
            number_bytes,
            slot,
            capacity,
            tail: TAIL,
            len: 0,
            slots: Pages::zeroed((capacity + TAIL) * slot + PAD, true),
        }
    }

    fn end(&self) -> usize {
        self.capacity + self.tail
    }

    fn home(&self, hash: u64) -> usize {
        ((u128::from(hash) * self.capacity as u128) >> 64) as usize
    }

    fn number(&self, i: usize) -> u32 {
        self.decode(&self.slots[i * self.slot + self.stride..])
    }

    /// The number whose bytes start `bytes` (4 of them readable).
    fn decode(&self, bytes: &[u8]) -> u32 {
        let word = u32::from_le_bytes(bytes[..4].try_into().expect("four bytes"));
        word & (u32::MAX >> (8 * (4 - self.number_bytes)))
    }

    fn set_number(&mut self, i: usize, n: u32) {
        let at = i * self.slot + self.stride;
        self.slots[at..at + self.number_bytes]
            .copy_from_slice(&n.to_le_bytes()[..self.number_bytes]);
    }

    /// The hash of marking `m` (which has PAD spare bytes).
    pub(crate) fn hash(&self, m: &[u8]) -> u64 {
        hash(m, self.stride)
    }

    /// Starts loading the home slot of `hash`, so lookups overlap.
    pub(crate) fn prefetch(&self, hash: u64) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let at = self.home(hash) * self.slot;
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
    pub(crate) fn full(&self) -> bool {
        (self.len + 1) * 20 > self.capacity * 17
    }

    /// The slot holding `m` (whose hash is `hash`), and its number; or, if
    /// `m` is new, the slot it is now written to numbered `n`, and EMPTY.
    pub(crate) fn find_or_insert(&mut self, hash: u64, m: &[u8], n: u32) -> (usize, u32) {
        let mut i = self.home(hash);
        loop {
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

    /// How many markings the table holds.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The markings held, in slot order.
    pub(crate) fn markings(&self) -> impl Iterator<Item = &[u8]> {
        (0..self.end())
            .filter(|&i| self.number(i) != EMPTY)
            .map(|i| &self.slots[i * self.slot..i * self.slot + self.stride])
    }

    /// A longer tail, for a cluster that ran off the end.
    fn lengthen(&mut self) {
        self.tail *= 2;
        self.slots.resize(self.end() * self.slot + PAD);
    }

    /// Grows the capacity in place, by half (doubling while small).
    ///
    /// Every entry is taken out once, last slot first, and put at the
    /// first slot from its new home that is empty or holds an entry not
    /// yet taken, which then changes places with it and is put in its
    /// turn. Entries put back never move again, so each probe path runs
    /// over entries already put back, as linear probing needs. A home only
    /// moves up as the capacity grows, so taking the last slots first finds
    /// free slots above, and entries seldom change places.
    pub(crate) fn grow(&mut self) {
        let old_end = self.end();
        self.capacity = if self.capacity < DOUBLE_BELOW {
            2 * self.capacity
        } else if self.capacity.is_power_of_two() {
            self.capacity + self.capacity / 2
        } else {
            self.capacity + self.capacity / 3
        };
        self.slots.resize(self.end() * self.slot + PAD);
        let mut placed = vec![0u64; self.end().div_ceil(64)];
        let mut entry = vec![0u8; self.slot + PAD];
        let mut other = vec![0u8; self.slot + PAD];
        for i in (0..old_end).rev() {
            let bit = |placed: &[u64], j: usize| placed[j / 64] >> (j % 64) & 1 == 1;
            if self.number(i) == EMPTY || bit(&placed, i) {
                continue;
            }
            let at = i * self.slot;
            entry[..self.slot].copy_from_slice(&self.slots[at..at + self.slot]);
            self.slots[at..at + self.slot].fill(0);
            loop {
                let mut j = self.home(self.hash(&entry));
                loop {
                    while j >= self.end() {
                        self.lengthen();
                        placed.resize(self.end().div_ceil(64), 0);
                    }
                    if !bit(&placed, j) {
                        break;
                    }
                    j += 1;
                }
                placed[j / 64] |= 1 << (j % 64);
                let at = j * self.slot;
                let taken = self.number(j) != EMPTY;
                if taken {
                    other[..self.slot].copy_from_slice(&self.slots[at..at + self.slot]);
                }
                let n = self.decode(&entry[self.stride..]);
                self.write(j, &entry[..self.stride], n);
                if !taken {
                    break;
                }
                std::mem::swap(&mut entry, &mut other);
            }
        }
    }
}

/// The hash of the marking of `stride` bytes `m` (which has PAD spare
/// bytes); its high bits choose its home in a [`MarkingTable`].
pub(crate) fn hash(m: &[u8], stride: usize) -> u64 {
    let h = if stride <= 16 {
        let [low, high] = words(m, stride);
        low ^ high.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(29)
    } else {
        let mut h = FxHasher::default();
        h.write(&m[..stride]);
        h.finish()
    };
    let h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^ (h >> 33)
}

/// Copies a marking of `stride` bytes into `to`, which has PAD spare bytes
/// (what follows the marking there may be overwritten); a short one as one
/// word, since a call to memcpy per firing costs more than the firing.
pub(crate) fn copy_marking(to: &mut [u8], from: &[u8], stride: usize) {
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

#[cfg(test)]
mod tests {
    use super::*;

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

    /// Through many growths, by doubling and by halves and thirds, every
    /// marking stays found under its own number, a second insertion finds
    /// it, and nothing is lost or added.
    #[test]
    fn the_table_keeps_every_marking_and_its_number_through_growth() {
        for (stride, number_bytes) in [(1, 3), (3, 4), (8, 3), (13, 4), (20, 3)] {
            let mut table = MarkingTable::new(stride, number_bytes);
            let mut numbers = Vec::new();
            let count = if stride == 1 { 256 } else { 150_000 };
            let mut distinct = std::collections::HashSet::new();
            for k in 0..count as u64 {
                let m = marking(k, stride);
                if !distinct.insert(m[..stride].to_vec()) {
                    continue;
                }
                let n = numbers.len() as u32 + 1;
                if table.full() {
                    table.grow();
                }
                let (slot, before) = table.find_or_insert(table.hash(&m), &m, n);
                assert_eq!(before, EMPTY, "stride {stride}: marking {k} is new");
                assert_eq!(table.number(slot), n);
                numbers.push((m, n));
            }
            assert!(table.capacity > 64, "the table grew");
            if count > DOUBLE_BELOW {
                assert!(
                    !table.capacity.is_power_of_two(),
                    "by halves and thirds too"
                );
            }
            for (m, n) in &numbers {
                let (slot, found) = table.find_or_insert(table.hash(m), m, 7);
                assert_eq!(found, *n, "stride {stride}: found under its number");
                assert_eq!(&table.slots[slot * table.slot..][..stride], &m[..stride]);
            }
            assert_eq!(table.len, numbers.len());
            let held = (0..table.end())
                .filter(|&i| table.number(i) != EMPTY)
                .count();
            assert_eq!(
                held,
                numbers.len(),
                "stride {stride}: nothing lost or added"
            );
        }
    }
}
