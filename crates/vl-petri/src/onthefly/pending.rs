//! What each state on the path has still to fire.

use crate::explore::Labels;
use crate::markings::Stack;

/// The transitions each frame on the path has still to fire, the top
/// frame's last, and the transition that reached each frame.
///
/// A net of at most 64 transitions keeps a bit mask per frame (2 bytes for
/// Kanban's 16), and leaves the bit of the transition it descends by set
/// until the child returns: the lowest bit then names the tree edge. A
/// larger net keeps per frame the transition it descended by (a byte for
/// up to 256 transitions), and the lists of what is left only for the
/// frames nearest the initial state: deeper ones list their transitions
/// again when the search returns to them (see [`Pending::resume`]). On a
/// strongly connected graph the path runs as deep as the graph is large,
/// and the lists would cost more than the markings.
pub(super) enum Pending {
    Masks(Stack),
    Lists {
        /// The top frame's transitions left, last first.
        top: Vec<u32>,
        /// Whether `top` is the top frame's (it is not when the search has
        /// just returned to a frame without a saved list).
        known: bool,
        by: Stack,
        /// The lists of the frames below the top and shallower than
        /// `saved_depth`, each closed by `separator` (the transition count).
        saved: Labels,
        separator: u32,
        saved_depth: usize,
    },
}

/// Frames shallower than this keep their lists (see [`Pending`]).
const SAVED_DEPTH: usize = 1 << 16;

impl Pending {
    pub(super) fn new(transitions: usize) -> Pending {
        if transitions <= 64 {
            Pending::Masks(Stack::new(transitions.div_ceil(8).max(1)))
        } else {
            Pending::Lists {
                top: Vec::new(),
                known: true,
                by: Stack::new(Labels::bytes(transitions)),
                saved: Labels::for_transitions(transitions + 1),
                separator: transitions as u32,
                saved_depth: SAVED_DEPTH,
            }
        }
    }

    /// A frame with `enabled` (in transition order) to fire.
    pub(super) fn push(&mut self, enabled: &[u32]) {
        match self {
            Pending::Masks(masks) => {
                masks.push(enabled.iter().fold(0u64, |m, &t| m | 1 << t));
            }
            Pending::Lists { top, known, .. } => {
                top.clear();
                top.extend(enabled.iter().rev());
                *known = true;
            }
        }
    }

    /// The top frame's next transitions, up to `out.len()` of them.
    pub(super) fn peek(&self, out: &mut [u32]) -> usize {
        match self {
            Pending::Masks(masks) => {
                let mut mask = masks.last().expect("a frame is open");
                let mut n = 0;
                while mask != 0 && n < out.len() {
                    out[n] = mask.trailing_zeros();
                    mask &= mask - 1;
                    n += 1;
                }
                n
            }
            Pending::Lists { top, .. } => {
                let n = top.len().min(out.len());
                for (o, &t) in out.iter_mut().zip(top.iter().rev()) {
                    *o = t;
                }
                n
            }
        }
    }

    /// Clears the lowest bit of the top mask.
    fn take_lowest(masks: &mut Stack) {
        let top = masks.len() - 1;
        let mask = masks.get(top);
        masks.set(top, mask & mask.wrapping_sub(1));
    }

    /// The top frame's next transition has been fired without descending.
    pub(super) fn take(&mut self) {
        match self {
            Pending::Masks(masks) => Pending::take_lowest(masks),
            Pending::Lists { top, .. } => {
                top.pop();
            }
        }
    }

    /// The top frame's next transition, `t`, reached a new state, whose
    /// frame comes next.
    pub(super) fn descend(&mut self, t: u32) {
        if let Pending::Lists {
            top,
            by,
            saved,
            separator,
            saved_depth,
            ..
        } = self
        {
            top.pop();
            if by.len() < *saved_depth {
                for &t in top.iter() {
                    saved.push(t);
                }
                saved.push(*separator);
            }
            by.push(u64::from(t));
        }
    }

    /// Removes the top frame, which has nothing left; with a parent below,
    /// the transition that reached it. A parent without a saved list then
    /// waits for [`Pending::resume`].
    pub(super) fn pop(&mut self) -> Option<u32> {
        match self {
            Pending::Masks(masks) => {
                masks.pop();
                let mask = masks.last()?;
                Pending::take_lowest(masks);
                Some(mask.trailing_zeros())
            }
            Pending::Lists {
                top,
                known,
                by,
                saved,
                separator,
                saved_depth,
            } => {
                let t = by.pop()? as u32;
                top.clear();
                *known = by.len() < *saved_depth;
                if *known {
                    // The list ends at the separator before it, if any.
                    let end = saved.len() - 1;
                    let mut start = end;
                    while start > 0 && saved.get(start - 1) != *separator {
                        start -= 1;
                    }
                    top.extend((start..end).map(|i| saved.get(i)));
                    saved.truncate(start);
                }
                Some(t)
            }
        }
    }

    /// The top frame is back from the child it reached by `by`; `enabled`
    /// lists what its marking enables, for a frame without a saved list to
    /// go on after `by`.
    pub(super) fn resume(&mut self, by: u32, enabled: impl FnOnce(&mut Vec<u32>)) {
        if let Pending::Lists { top, known, .. } = self
            && !*known
        {
            enabled(top);
            top.retain(|&t| t > by);
            top.reverse();
            *known = true;
        }
    }

    /// The same, saving the lists of only the `depth` frames nearest the
    /// initial state, so a test reaches the lists made again.
    #[cfg(test)]
    pub(super) fn saving(mut self, depth: usize) -> Pending {
        if let Pending::Lists { saved_depth, .. } = &mut self {
            *saved_depth = depth;
        }
        self
    }
}
