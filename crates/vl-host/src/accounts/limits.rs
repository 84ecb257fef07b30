//! How many failed logins an address, and an account from an address,
//! may have: a burst, then one more per refill time. Full allowances are
//! forgotten first when too many addresses are remembered.

use std::collections::HashMap;
use std::net::IpAddr;
use std::time::Duration;

use tokio::time::Instant;

/// Failures an address, or an account from an address, may have at once…
pub const FAILURES_BURST: f64 = 10.0;
/// …and how often one more is allowed after those.
pub const FAILURE_REFILL: Duration = Duration::from_secs(6);
/// Addresses (and address–account pairs) whose failures are remembered,
/// at most.
const MAX_ADDRESSES: usize = 4096;

/// Failures allowed, refilling over time.
#[derive(Debug, Clone, Copy)]
struct Allowance {
    left: f64,
    at: Instant,
}

impl Allowance {
    fn full() -> Allowance {
        Allowance {
            left: FAILURES_BURST,
            at: Instant::now(),
        }
    }

    fn now(&mut self) -> f64 {
        let refill = self.at.elapsed().as_secs_f64() / FAILURE_REFILL.as_secs_f64();
        self.left = (self.left + refill).min(FAILURES_BURST);
        self.at = Instant::now();
        self.left
    }
}

/// Allowances by key, at most [`MAX_ADDRESSES`]: full ones are forgotten
/// first, and one rather than refuse everyone new.
struct Allowances<K>(HashMap<K, Allowance>);

impl<K: std::hash::Hash + Eq + Clone> Allowances<K> {
    fn left(&mut self, key: &K) -> bool {
        self.0.get_mut(key).is_none_or(|a| a.now() >= 1.0)
    }

    fn take(&mut self, key: K) {
        if self.0.len() >= MAX_ADDRESSES && !self.0.contains_key(&key) {
            self.0.retain(|_, a| a.now() < FAILURES_BURST);
            if self.0.len() >= MAX_ADDRESSES {
                let some = self.0.keys().next().cloned();
                if let Some(some) = some {
                    self.0.remove(&some);
                }
            }
        }
        let a = self.0.entry(key).or_insert_with(Allowance::full);
        a.now();
        a.left -= 1.0;
    }

    fn give(&mut self, key: &K) {
        if let Some(a) = self.0.get_mut(key) {
            a.left = (a.left + 1.0).min(FAILURES_BURST);
        }
    }
}

impl<K> Default for Allowances<K> {
    fn default() -> Self {
        Allowances(HashMap::new())
    }
}

#[derive(Default)]
pub(super) struct Failures {
    by_address: Allowances<IpAddr>,
    /// An account guessed at from an address: the guesser's, not the
    /// account's — its owner elsewhere is never slowed by it.
    by_pair: Allowances<(IpAddr, String)>,
}

impl Failures {
    /// Takes one failure's worth of allowance from `address` (and
    /// `account` from it) for an attempt about to be checked: false,
    /// taking nothing, when either has none left. Taken before the check,
    /// so attempts checked at once cannot pass the limit together.
    pub(super) fn take(&mut self, address: IpAddr, account: Option<&str>) -> bool {
        let pair = account.map(|name| (address, name.to_owned()));
        let pair_left = pair.as_ref().is_none_or(|p| self.by_pair.left(p));
        if !pair_left || !self.by_address.left(&address) {
            return false;
        }
        self.by_address.take(address);
        if let Some(pair) = pair {
            self.by_pair.take(pair);
        }
        true
    }

    /// Gives back what an attempt that succeeded took.
    pub(super) fn refund(&mut self, address: IpAddr, account: Option<&str>) {
        self.by_address.give(&address);
        if let Some(name) = account {
            self.by_pair.give(&(address, name.to_owned()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_failures_remembered_are_bounded() {
        let mut failures = Failures::default();
        for n in 0..(MAX_ADDRESSES as u32 + 100) {
            failures.take(IpAddr::from(n.to_be_bytes()), None);
        }
        assert!(failures.by_address.0.len() <= MAX_ADDRESSES);
    }
}
