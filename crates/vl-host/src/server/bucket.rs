//! A token bucket: what a client may do at a rate, with a burst. The
//! connection reads a client's messages and bytes within two; the hub takes
//! the points of the operator's definitions within one.

use std::time::{Duration, Instant};

/// A token bucket, `rate` a second and `burst` at once, that may be
/// overdrawn: the overdraft says how long to wait before taking more.
pub struct Bucket {
    rate: f64,
    burst: f64,
    tokens: f64,
    last: Instant,
}

impl Bucket {
    pub fn new(rate: f64, burst: f64) -> Bucket {
        Bucket {
            rate,
            burst,
            tokens: burst,
            last: Instant::now(),
        }
    }

    /// Gives back `amount` taken for something that never went ahead.
    pub fn refund(&mut self, amount: f64) {
        self.tokens = (self.tokens + amount).min(self.burst);
    }

    /// Takes `amount`; how long until the bucket is out of debt.
    pub fn take(&mut self, amount: f64) -> Duration {
        let now = Instant::now();
        let refill = now.duration_since(self.last).as_secs_f64() * self.rate;
        self.tokens = (self.tokens + refill).min(self.burst) - amount;
        self.last = now;
        Duration::from_secs_f64((-self.tokens).max(0.0) / self.rate)
    }
}
