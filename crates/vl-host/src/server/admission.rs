//! Who gets a connection: at most [`MAX_CONNECTIONS`] at once, of which at
//! most [`MAX_UNWELCOMED`] have not said hello yet. A new connection
//! pushes out the oldest one still silent, so idle sockets — however many
//! a client opens — never lock a newcomer out.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

use tokio::sync::watch;

/// Connections the Host serves at once.
pub(crate) const MAX_CONNECTIONS: usize = 64;
/// Of those, connections that have not been welcomed yet.
pub(crate) const MAX_UNWELCOMED: usize = 16;

#[derive(Default)]
struct Counts {
    total: usize,
    /// Connections not yet welcomed, oldest first, with their eviction signal.
    unwelcomed: VecDeque<(u64, watch::Sender<bool>)>,
}

/// The Host's connection slots.
#[derive(Clone, Default)]
pub(crate) struct Admission {
    counts: Arc<Mutex<Counts>>,
}

/// A connection's slot; dropping it frees the slot.
pub(crate) struct Ticket {
    id: u64,
    counts: Arc<Mutex<Counts>>,
    /// Becomes true when the connection is pushed out.
    pub(crate) evicted: watch::Receiver<bool>,
}

fn lock(counts: &Mutex<Counts>) -> MutexGuard<'_, Counts> {
    counts
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Admission {
    pub(crate) fn new() -> Admission {
        Admission::default()
    }

    /// A slot for connection `id`, pushing out the oldest silent connection
    /// if the slots are full; none when every slot holds a welcomed client.
    pub(crate) fn admit(&self, id: u64) -> Option<Ticket> {
        let mut counts = lock(&self.counts);
        let full = counts.total >= MAX_CONNECTIONS || counts.unwelcomed.len() >= MAX_UNWELCOMED;
        if full {
            let (_, evict) = counts.unwelcomed.pop_front()?;
            let _ = evict.send(true);
            // The evicted connection frees its place in the total when it ends.
        }
        if counts.total >= MAX_CONNECTIONS + MAX_UNWELCOMED {
            return None;
        }
        counts.total += 1;
        let (evict, evicted) = watch::channel(false);
        counts.unwelcomed.push_back((id, evict));
        Some(Ticket {
            id,
            counts: self.counts.clone(),
            evicted,
        })
    }
}

impl Ticket {
    /// The connection was welcomed: it no longer counts as silent.
    pub(crate) fn welcomed(&self) {
        lock(&self.counts)
            .unwelcomed
            .retain(|(id, _)| *id != self.id);
    }

    pub(crate) fn is_welcomed(&self) -> bool {
        !lock(&self.counts)
            .unwelcomed
            .iter()
            .any(|(id, _)| *id == self.id)
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut counts = lock(&self.counts);
        counts.total -= 1;
        counts.unwelcomed.retain(|(id, _)| *id != self.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_oldest_silent_connection_makes_room() {
        let admission = Admission::new();
        let silent: Vec<Ticket> = (0..MAX_UNWELCOMED as u64)
            .map(|id| admission.admit(id).unwrap())
            .collect();
        let newcomer = admission.admit(100).expect("admitted");
        assert!(*silent[0].evicted.borrow(), "the oldest was pushed out");
        assert!(!*silent[1].evicted.borrow());
        newcomer.welcomed();
        drop(silent);
        // Welcomed clients fill the Host; then a newcomer has no room.
        let welcomed: Vec<Ticket> = (200..200 + MAX_CONNECTIONS as u64 - 1)
            .map(|id| {
                let t = admission.admit(id).unwrap();
                t.welcomed();
                t
            })
            .collect();
        assert_eq!(welcomed.len() + 1, MAX_CONNECTIONS);
        assert!(
            admission.admit(999).is_none(),
            "every slot holds a welcomed client"
        );
        drop((welcomed, newcomer));
        assert_eq!(lock(&admission.counts).total, 0);
        assert!(admission.admit(1000).is_some());
    }
}
