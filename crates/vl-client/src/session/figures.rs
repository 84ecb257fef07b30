//! The running figures a session keeps: its round trips and their
//! percentiles, and running errors (mean and maximum).

use std::collections::VecDeque;

use serde::Serialize;

/// Round-trip samples kept for the percentiles.
const RTT_KEPT: usize = 10_000;

/// Round-trip times measured on this connection, ms.
#[derive(Debug, Clone, Default)]
pub struct RoundTrips {
    /// The newest [`RTT_KEPT`], oldest first.
    samples: VecDeque<f64>,
}

impl RoundTrips {
    pub fn push(&mut self, ms: f64) {
        if self.samples.len() == RTT_KEPT {
            self.samples.pop_front();
        }
        self.samples.push_back(ms);
    }

    pub fn last(&self) -> Option<f64> {
        self.samples.back().copied()
    }

    pub fn count(&self) -> usize {
        self.samples.len()
    }

    /// The `q`-quantile (0..=1), nearest rank.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        let mut sorted: Vec<f64> = self.samples.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        vl_core::nearest_rank(&sorted, q)
    }
}

/// A running mean and maximum, mm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct MeanMax {
    pub count: u64,
    pub mean: f64,
    pub max: f64,
}

impl MeanMax {
    pub fn add(&mut self, v: f64) {
        self.count += 1;
        self.mean += (v - self.mean) / self.count as f64;
        self.max = self.max.max(v);
    }
}

/// Percentiles of the round-trip time, ms.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct RoundTripMs {
    pub p50: f64,
    pub p99: f64,
}

impl RoundTripMs {
    /// The percentiles in a table cell.
    pub(crate) fn cell(&self) -> String {
        format!("p50 {:.2} ms, p99 {:.2} ms", self.p50, self.p99)
    }
}

impl From<&RoundTrips> for RoundTripMs {
    fn from(rtt: &RoundTrips) -> RoundTripMs {
        RoundTripMs {
            p50: rtt.quantile(0.5).unwrap_or(f64::NAN),
            p99: rtt.quantile(0.99).unwrap_or(f64::NAN),
        }
    }
}
