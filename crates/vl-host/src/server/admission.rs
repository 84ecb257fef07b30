//! Who gets a connection: at most [`MAX_CONNECTIONS`] at once, of which at
//! most [`MAX_UNWELCOMED`] have not said hello yet, and at most
//! [`MAX_UNWELCOMED_PER_ADDRESS`] of those from one address. A newcomer
//! pushes out the oldest silent connection of its own address when that
//! address has used its budget, and otherwise the oldest silent one of the
//! address holding the most: however many idle sockets one machine opens,
//! they only ever push out each other, never a person connecting from
//! elsewhere over a slow link. Of one address's, the one least far on
//! goes first: a bare socket before one that finished its handshake, and
//! that before one that said hello and waits for its welcome. Of the
//! welcomed places, the last
//! [`KEPT_FOR_DRIVERS`] are kept for people who may drive: however many
//! come to watch, an operator still gets in.

use std::collections::{HashSet, VecDeque};
use std::net::IpAddr;
use std::sync::{Arc, Mutex, MutexGuard};

use tokio::sync::watch;

/// Connections the Host serves at once: a class of a hundred watching, and room.
pub(crate) const MAX_CONNECTIONS: usize = 256;
/// Of those, connections that have not been welcomed yet.
pub(crate) const MAX_UNWELCOMED: usize = 128;
/// Of those, connections from one address: a class of thirty behind one
/// router (or one `vl media`) connecting at once with a page and Foxglove
/// each, saying hello within a round trip and waiting their turn for the
/// password check.
pub(crate) const MAX_UNWELCOMED_PER_ADDRESS: usize = 64;
/// Welcomed places only people who may drive take.
pub(crate) const KEPT_FOR_DRIVERS: usize = 16;

/// How far a connection not yet welcomed has come: the least far on is
/// pushed out first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Stage {
    /// A socket, without its WebSocket handshake yet.
    Bare,
    /// A WebSocket that has said nothing yet.
    Upgraded,
    /// It said hello, and waits for its credentials to be checked and for
    /// its welcome: a person's client, where a flood's never gets.
    Greeted,
}

/// A connection not yet welcomed, with its eviction signal.
struct Silent {
    id: u64,
    address: IpAddr,
    stage: Stage,
    evict: watch::Sender<bool>,
}

#[derive(Default)]
struct Counts {
    /// Connections served at once (welcomed, or not yet).
    capacity: usize,
    total: usize,
    /// Connections not yet welcomed, oldest first.
    unwelcomed: VecDeque<Silent>,
    /// Connections seated to watch only.
    watching: HashSet<u64>,
}

impl Counts {
    fn from(&self, address: IpAddr) -> usize {
        self.unwelcomed
            .iter()
            .filter(|s| s.address == address)
            .count()
    }

    /// Pushes out the oldest of the silent connections from `address` that
    /// have come least far.
    fn evict_oldest_of(&mut self, address: IpAddr) -> bool {
        // The first of equal minima: the oldest of those least far on.
        let Some(at) = self
            .unwelcomed
            .iter()
            .enumerate()
            .filter(|(_, s)| s.address == address)
            .min_by_key(|(_, s)| s.stage)
            .map(|(at, _)| at)
        else {
            return false;
        };
        if let Some(silent) = self.unwelcomed.remove(at) {
            // The evicted connection frees its place in the total when it ends.
            let _ = silent.evict.send(true);
        }
        true
    }

    /// The address holding the most silent connections: of several that
    /// hold as many, the one met first, oldest first, so the one whose
    /// oldest has waited longest.
    fn greediest(&self) -> Option<IpAddr> {
        let mut greediest = None;
        let mut most = 0;
        for silent in &self.unwelcomed {
            let held = self.from(silent.address);
            if held > most {
                (greediest, most) = (Some(silent.address), held);
            }
        }
        greediest
    }
}

/// The Host's connection slots.
#[derive(Clone)]
pub struct Admission {
    counts: Arc<Mutex<Counts>>,
}

/// A connection's slot; dropping it frees the slot.
pub struct Ticket {
    id: u64,
    counts: Arc<Mutex<Counts>>,
    /// Becomes true when the connection is pushed out.
    pub evicted: watch::Receiver<bool>,
}

fn lock(counts: &Mutex<Counts>) -> MutexGuard<'_, Counts> {
    counts
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Admission {
    pub(crate) fn new() -> Admission {
        Admission::with_capacity(MAX_CONNECTIONS)
    }

    /// Slots for `capacity` connections at once (a gateway serves a
    /// class of hundreds: its watchers cost its cells nothing).
    pub fn with_capacity(capacity: usize) -> Admission {
        let counts = Counts {
            capacity,
            ..Counts::default()
        };
        Admission {
            counts: Arc::new(Mutex::new(counts)),
        }
    }

    /// A slot for connection `id` from `address`, pushing out a silent
    /// connection if the slots are full; none when every slot holds a
    /// welcomed client.
    pub(crate) fn admit(&self, id: u64, address: IpAddr) -> Option<Ticket> {
        let mut counts = lock(&self.counts);
        if counts.from(address) >= MAX_UNWELCOMED_PER_ADDRESS {
            counts.evict_oldest_of(address);
        } else if counts.total >= counts.capacity || counts.unwelcomed.len() >= MAX_UNWELCOMED {
            let greediest = counts.greediest()?;
            counts.evict_oldest_of(greediest);
        }
        if counts.total >= counts.capacity + MAX_UNWELCOMED {
            return None;
        }
        counts.total += 1;
        let (evict, evicted) = watch::channel(false);
        counts.unwelcomed.push_back(Silent {
            id,
            address,
            stage: Stage::Bare,
            evict,
        });
        Some(Ticket {
            id,
            counts: self.counts.clone(),
            evicted,
        })
    }
}

impl Ticket {
    /// The connection finished its WebSocket handshake: it is further on
    /// than a bare socket, which is pushed out before it.
    pub(crate) fn upgraded(&self) {
        self.came_to(Stage::Upgraded);
    }

    /// The connection said hello: it is pushed out only after those from
    /// its address that have not.
    pub(crate) fn greeted(&self) {
        self.came_to(Stage::Greeted);
    }

    fn came_to(&self, stage: Stage) {
        if let Some(silent) = lock(&self.counts)
            .unwelcomed
            .iter_mut()
            .find(|s| s.id == self.id)
        {
            silent.stage = silent.stage.max(stage);
        }
    }

    /// The connection was welcomed: it no longer counts as silent.
    pub fn welcomed(&self) {
        lock(&self.counts).unwelcomed.retain(|s| s.id != self.id);
    }

    /// Takes a place for this connection's person: any place for one who
    /// may drive, one not kept for drivers for one who only watches.
    /// Whether there was one.
    pub fn seat(&self, may_drive: bool) -> bool {
        let mut counts = lock(&self.counts);
        if may_drive || counts.watching.contains(&self.id) {
            return true;
        }
        if counts.watching.len() >= counts.capacity - KEPT_FOR_DRIVERS {
            return false;
        }
        counts.watching.insert(self.id);
        true
    }

    pub(crate) fn is_welcomed(&self) -> bool {
        !lock(&self.counts)
            .unwelcomed
            .iter()
            .any(|s| s.id == self.id)
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut counts = lock(&self.counts);
        counts.total -= 1;
        counts.unwelcomed.retain(|s| s.id != self.id);
        counts.watching.remove(&self.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HERE: IpAddr = IpAddr::V4(std::net::Ipv4Addr::new(127, 0, 0, 1));

    fn address(n: u8) -> IpAddr {
        IpAddr::V4(std::net::Ipv4Addr::new(10, 0, 0, n))
    }

    #[test]
    fn the_oldest_silent_connection_makes_room() {
        let admission = Admission::new();
        // Silent connections from many addresses fill the unwelcomed slots.
        let silent: Vec<Ticket> = (0..MAX_UNWELCOMED as u64)
            .map(|id| admission.admit(id, address(id as u8 / 4)).unwrap())
            .collect();
        let newcomer = admission.admit(100, HERE).expect("admitted");
        assert!(*silent[0].evicted.borrow(), "the oldest was pushed out");
        assert!(!*silent[1].evicted.borrow());
        newcomer.welcomed();
        drop(silent);
        // Welcomed clients fill the Host; then a newcomer has no room.
        let welcomed: Vec<Ticket> = (200..200 + MAX_CONNECTIONS as u64 - 1)
            .map(|id| {
                let t = admission.admit(id, HERE).unwrap();
                t.welcomed();
                t
            })
            .collect();
        assert_eq!(welcomed.len() + 1, MAX_CONNECTIONS);
        assert!(
            admission.admit(999, HERE).is_none(),
            "every slot holds a welcomed client"
        );
        drop((welcomed, newcomer));
        assert_eq!(lock(&admission.counts).total, 0);
        assert!(admission.admit(1000, HERE).is_some());
    }

    #[test]
    fn watchers_never_take_the_places_kept_for_drivers() {
        let admission = Admission::new();
        let watchers: Vec<Ticket> = (0..(MAX_CONNECTIONS - KEPT_FOR_DRIVERS) as u64)
            .map(|id| {
                let t = admission.admit(id, address(id as u8)).unwrap();
                assert!(t.seat(false), "watcher {id} seated");
                t.welcomed();
                t
            })
            .collect();
        let late = admission.admit(5000, HERE).unwrap();
        assert!(!late.seat(false), "no place left to watch from");
        drop(late);
        let drivers: Vec<Ticket> = (0..KEPT_FOR_DRIVERS as u64)
            .map(|n| {
                let t = admission.admit(6000 + n, HERE).unwrap();
                assert!(t.seat(true), "driver {n} seated");
                t.welcomed();
                t
            })
            .collect();
        assert!(admission.admit(7000, HERE).is_none(), "the Host is full");
        // A watcher who leaves frees a place to watch from.
        drop(watchers.into_iter().next());
        let next = admission.admit(8000, HERE).unwrap();
        assert!(next.seat(false));
        drop(drivers);
    }

    /// A person on the same machine as a flood (a lab's own desktop, a
    /// class behind one router) keeps their connection once it said hello,
    /// however many bare and silent sockets come after it.
    #[test]
    fn a_connection_that_said_hello_goes_after_those_that_did_not() {
        let admission = Admission::new();
        let person = admission.admit(1, HERE).unwrap();
        person.upgraded();
        person.greeted();
        let mut flood = Vec::new();
        for id in 2..1000 {
            let t = admission.admit(id, HERE).unwrap();
            if id % 2 == 0 {
                t.upgraded();
            }
            flood.push(t);
            flood.retain(|t: &Ticket| !*t.evicted.borrow());
            assert!(flood.len() < MAX_UNWELCOMED_PER_ADDRESS);
        }
        assert!(!*person.evicted.borrow(), "the person was pushed out");
        // Bare sockets go before upgraded ones.
        let upgraded = flood.iter().filter(|t| t.id % 2 == 0).count();
        assert!(upgraded >= MAX_UNWELCOMED_PER_ADDRESS - 2, "{upgraded}");
        // Only when every one from the address said hello is the oldest
        // of those pushed out.
        for t in &flood {
            t.greeted();
        }
        admission.admit(5000, HERE).unwrap();
        assert!(*person.evicted.borrow());
    }

    #[test]
    fn one_address_pushes_out_only_its_own() {
        let admission = Admission::new();
        let person = admission.admit(1, address(7)).unwrap();
        // A flood of bare connects from one machine, far more than the slots.
        let mut flood = Vec::new();
        for id in 2..1000 {
            flood.push(admission.admit(id, HERE).unwrap());
            flood.retain(|t: &Ticket| !*t.evicted.borrow());
            assert!(flood.len() <= MAX_UNWELCOMED_PER_ADDRESS);
        }
        assert!(!*person.evicted.borrow(), "the person was never pushed out");
        // Many addresses filling the slots push out the greediest first:
        // the flood's, not the person's nor the other newcomers'.
        let room = MAX_UNWELCOMED - 2;
        let others: Vec<Ticket> = (0..room as u8)
            .map(|n| {
                admission
                    .admit(2000 + u64::from(n), address(100 + n))
                    .unwrap()
            })
            .collect();
        assert_eq!(flood.iter().filter(|t| !*t.evicted.borrow()).count(), 1);
        assert!(!*person.evicted.borrow());
        assert!(others.iter().all(|t| !*t.evicted.borrow()));
    }
}
