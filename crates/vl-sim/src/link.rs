//! The Media as a model: one direction of an Internet link in virtual time,
//! in the vocabulary of Linux netem — delay with jitter, correlation and a
//! distribution, random or Gilbert–Elliott loss, duplication, reordering, a
//! rate limit and scheduled disconnects.
//!
//! Correlation is an AR(1) process on a standard normal variable mapped
//! through its CDF (a Gaussian copula), so successive delays are related
//! while each one keeps exactly the configured distribution — netem's own
//! "next = (1−ρ)·random + ρ·last" shrinks the jitter as ρ grows. Pareto-based
//! distributions are sampled, as netem does, from a 4096-entry table of
//! quantiles, standardised to mean 0 and deviation 1: delay = mean + jitter·X.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use vl_core::Named;
use vl_report::table::{Report, Table};

use crate::noise::gaussian;

/// How delays spread around their mean.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Distribution {
    /// Uniform on [mean − jitter, mean + jitter].
    Uniform,
    /// Normal with deviation `jitter`.
    Normal,
    /// Pareto (shape 3), standardised: deviation `jitter`, a heavy upper tail.
    Pareto,
    /// netem's paretonormal: 0.25·normal + 0.75·Pareto, standardised.
    ParetoNormal,
}

/// When packets are lost.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Loss {
    None,
    /// Each packet with probability `p`, successive decisions correlated by `correlation`.
    Random {
        p: f64,
        correlation: f64,
    },
    /// Gilbert–Elliott: Good → Bad with probability `p`, Bad → Good with `r`;
    /// a packet is lost with probability `bad_loss` in Bad and `good_loss` in Good.
    GilbertElliott {
        p: f64,
        r: f64,
        bad_loss: f64,
        good_loss: f64,
    },
}

/// One direction of a link, as netem would be configured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkModel {
    pub delay_ms: f64,
    pub jitter_ms: f64,
    pub correlation: f64,
    pub distribution: Distribution,
    pub loss: Loss,
    pub duplicate: f64,
    /// Probability a packet skips the delay (and so overtakes others).
    pub reorder: f64,
    /// Bytes per second the link carries; None for unlimited.
    pub rate_bytes_s: Option<f64>,
    /// Intervals [start, end) in ms during which every packet is lost.
    pub disconnects: Vec<(f64, f64)>,
}

/// The named links between a Guest and a Host, from a lab's LAN to a
/// geostationary satellite hop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    Lan,
    Internet2,
    Internet2005,
    Intercontinental,
    Congested,
    GeoSatellite,
}

impl Named for Profile {
    const KIND: &'static str = "link profile";
    const ALL: &'static [Self] = &[
        Profile::Lan,
        Profile::Internet2,
        Profile::Internet2005,
        Profile::Intercontinental,
        Profile::Congested,
        Profile::GeoSatellite,
    ];

    fn id(self) -> &'static str {
        match self {
            Profile::Lan => "lan",
            Profile::Internet2 => "internet2",
            Profile::Internet2005 => "internet-2005",
            Profile::Intercontinental => "intercontinental",
            Profile::Congested => "congested",
            Profile::GeoSatellite => "geo-satellite",
        }
    }
}

vl_core::named_by_id!(Profile);

impl LinkModel {
    fn delay(
        delay_ms: f64,
        jitter_ms: f64,
        correlation: f64,
        distribution: Distribution,
    ) -> LinkModel {
        LinkModel {
            delay_ms,
            jitter_ms,
            correlation,
            distribution,
            loss: Loss::None,
            duplicate: 0.0,
            reorder: 0.0,
            rate_bytes_s: None,
            disconnects: Vec::new(),
        }
    }

    fn gemodel(p: f64, r: f64) -> Loss {
        Loss::GilbertElliott {
            p,
            r,
            bad_loss: 1.0,
            good_loss: 0.0,
        }
    }

    /// A named profile: one-way delay per direction, as netem arguments.
    pub fn profile(profile: Profile) -> LinkModel {
        use Distribution::*;
        match profile {
            // delay 0.5ms 0.1ms
            Profile::Lan => LinkModel::delay(0.5, 0.1, 0.0, Uniform),
            // delay 12ms 2ms 25% distribution normal loss 0.1%
            Profile::Internet2 => LinkModel {
                loss: Loss::Random {
                    p: 0.001,
                    correlation: 0.0,
                },
                ..LinkModel::delay(12.0, 2.0, 0.25, Normal)
            },
            // delay 40ms 15ms 25% distribution paretonormal loss gemodel 0.505% 50%
            Profile::Internet2005 => LinkModel {
                loss: LinkModel::gemodel(0.00505, 0.5),
                ..LinkModel::delay(40.0, 15.0, 0.25, ParetoNormal)
            },
            // delay 75ms 15ms 25% distribution normal loss gemodel 0.505% 50%
            Profile::Intercontinental => LinkModel {
                loss: LinkModel::gemodel(0.00505, 0.5),
                ..LinkModel::delay(75.0, 15.0, 0.25, Normal)
            },
            // delay 100ms 50ms distribution pareto loss gemodel 1% 33% reorder 2% 50%
            Profile::Congested => LinkModel {
                loss: LinkModel::gemodel(0.01, 0.33),
                reorder: 0.02,
                ..LinkModel::delay(100.0, 50.0, 0.0, Pareto)
            },
            // delay 280ms 10ms loss 0.5%
            Profile::GeoSatellite => LinkModel {
                loss: Loss::Random {
                    p: 0.005,
                    correlation: 0.0,
                },
                ..LinkModel::delay(280.0, 10.0, 0.0, Uniform)
            },
        }
    }

    /// The long-run fraction of packets lost (disconnects aside).
    pub fn expected_loss(&self) -> f64 {
        match self.loss {
            Loss::None => 0.0,
            Loss::Random { p, .. } => p,
            Loss::GilbertElliott {
                p,
                r,
                bad_loss,
                good_loss,
            } => {
                let bad = p / (p + r);
                bad * bad_loss + (1.0 - bad) * good_loss
            }
        }
    }

    /// The mean length of a run of consecutive losses.
    pub fn expected_burst(&self) -> f64 {
        match self.loss {
            Loss::None => 0.0,
            Loss::Random { p, .. } => 1.0 / (1.0 - p),
            // With every Bad packet lost and no Good one, a burst is a stay in Bad.
            Loss::GilbertElliott { r, .. } => 1.0 / r,
        }
    }

    /// The mean one-way delay the model aims at: reordered packets skip the delay.
    pub fn expected_delay(&self) -> f64 {
        (1.0 - self.reorder) * self.delay_ms
    }

    /// The deviation of the delay the model aims at (of the mixture, when
    /// some packets are reordered past the delay).
    pub fn expected_jitter(&self) -> f64 {
        let sd = match self.distribution {
            Distribution::Uniform => self.jitter_ms / 3f64.sqrt(),
            _ => self.jitter_ms,
        };
        let kept = 1.0 - self.reorder;
        let second_moment = kept * (sd * sd + self.delay_ms * self.delay_ms);
        (second_moment - self.expected_delay().powi(2)).sqrt()
    }
}

/// Entries in the quantile tables, as netem's.
const TABLE: usize = 4096;

/// A running link: the model plus its random state.
pub struct Link {
    model: LinkModel,
    rng: Pcg64Mcg,
    /// The AR(1) state of the delay's normal variable.
    z: f64,
    /// The AR(1) state of the random-loss decision.
    loss_z: f64,
    bad: bool,
    /// When the link finishes sending the last packet (rate limit), ms.
    busy_until: f64,
    table: Option<Vec<f64>>,
}

impl Link {
    pub fn new(model: LinkModel, seed: u64) -> Link {
        let table = match model.distribution {
            Distribution::Pareto => Some(standardised(pareto)),
            Distribution::ParetoNormal => Some(pareto_normal_table()),
            _ => None,
        };
        Link {
            model,
            rng: Pcg64Mcg::seed_from_u64(seed),
            z: 0.0,
            loss_z: 0.0,
            bad: false,
            busy_until: f64::NEG_INFINITY,
            table,
        }
    }

    pub fn model(&self) -> &LinkModel {
        &self.model
    }

    /// An AR(1) step that keeps the variable standard normal.
    fn correlated(&mut self, previous: f64, rho: f64) -> f64 {
        let e = gaussian(&mut self.rng);
        rho * previous + (1.0 - rho * rho).sqrt() * e
    }

    fn lost(&mut self) -> bool {
        match self.model.loss {
            Loss::None => false,
            Loss::Random { p, correlation } => {
                self.loss_z = self.correlated(self.loss_z, correlation);
                normal_cdf(self.loss_z) < p
            }
            Loss::GilbertElliott {
                p,
                r,
                bad_loss,
                good_loss,
            } => {
                let flip: f64 = self.rng.random();
                self.bad = if self.bad { flip >= r } else { flip < p };
                let loss = if self.bad { bad_loss } else { good_loss };
                self.rng.random::<f64>() < loss
            }
        }
    }

    fn delay(&mut self) -> f64 {
        self.z = self.correlated(self.z, self.model.correlation);
        let u = normal_cdf(self.z);
        let x = match (&self.table, self.model.distribution) {
            (Some(table), _) => table[((u * TABLE as f64) as usize).min(TABLE - 1)],
            (None, Distribution::Uniform) => 2.0 * u - 1.0,
            (None, _) => self.z,
        };
        (self.model.delay_ms + self.model.jitter_ms * x).max(0.0)
    }

    /// Sends a packet of `bytes` at `t_ms`: the times (ms) its copies arrive —
    /// none if it is lost, two if it is duplicated — never before `t_ms`.
    pub fn send(&mut self, t_ms: f64, bytes: usize) -> Vec<f64> {
        let lost = self.lost();
        self.deliver(t_ms, bytes, lost)
    }

    /// Sends a retransmission: it is lost at the long-run rate, as a burst
    /// of losses has passed by the time a retransmission timer fires.
    pub(crate) fn resend(&mut self, t_ms: f64, bytes: usize) -> Vec<f64> {
        let lost = self.rng.random::<f64>() < self.model.expected_loss();
        self.deliver(t_ms, bytes, lost)
    }

    fn deliver(&mut self, t_ms: f64, bytes: usize, lost: bool) -> Vec<f64> {
        let mut departs = t_ms;
        if let Some(rate) = self.model.rate_bytes_s {
            departs = departs.max(self.busy_until) + bytes as f64 / rate * 1e3;
            self.busy_until = departs;
        }
        let disconnected = self
            .model
            .disconnects
            .iter()
            .any(|&(a, b)| (a..b).contains(&t_ms));
        if lost || disconnected {
            return Vec::new();
        }
        let reordered = self.rng.random::<f64>() < self.model.reorder;
        let arrival = departs + if reordered { 0.0 } else { self.delay() };
        if self.rng.random::<f64>() < self.model.duplicate {
            let copy = departs + self.delay();
            vec![arrival, copy]
        } else {
            vec![arrival]
        }
    }
}

/// Pareto(shape 3, scale 1) at quantile `u`.
fn pareto(u: f64) -> f64 {
    (1.0 - u).max(1e-12).powf(-1.0 / 3.0)
}

/// A quantile table of `quantile`, shifted and scaled to mean 0, deviation 1.
fn standardised(quantile: impl Fn(f64) -> f64) -> Vec<f64> {
    standardise(
        (0..TABLE)
            .map(|i| quantile((i as f64 + 0.5) / TABLE as f64))
            .collect(),
    )
}

/// The quantiles of 0.25·N + 0.75·P for independent normal N and Pareto P,
/// as iproute2 builds netem's table: from a large fixed-seed sample, sorted.
fn pareto_normal_table() -> Vec<f64> {
    const SAMPLES: usize = 1 << 18;
    let mut rng = Pcg64Mcg::seed_from_u64(0x7061_7265_746f);
    let mut sums: Vec<f64> = (0..SAMPLES)
        .map(|_| {
            let n = normal_quantile(rng.random::<f64>());
            0.25 * n + 0.75 * pareto(rng.random::<f64>())
        })
        .collect();
    sums.sort_by(f64::total_cmp);
    standardise(
        (0..TABLE)
            .map(|i| sums[(i * SAMPLES + SAMPLES / 2) / TABLE])
            .collect(),
    )
}

/// `raw` shifted and scaled to mean 0, deviation 1.
fn standardise(raw: Vec<f64>) -> Vec<f64> {
    let mean = raw.iter().sum::<f64>() / TABLE as f64;
    let sd = (raw.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / TABLE as f64).sqrt();
    raw.iter().map(|v| (v - mean) / sd).collect()
}

/// Φ, the standard normal CDF (Abramowitz & Stegun 7.1.26 via erf).
fn normal_cdf(z: f64) -> f64 {
    0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2))
}

fn erf(x: f64) -> f64 {
    // W. J. Cody's rational approximation is overkill here; A&S 7.1.26 has
    // error below 1.5e-7, far finer than any delay resolution.
    let sign = x.signum();
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    sign * (1.0 - poly * (-x * x).exp())
}

/// Φ⁻¹ (Acklam's approximation, relative error below 1.2e-9).
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let p = p.clamp(1e-15, 1.0 - 1e-15);
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// What `packets` packets sent every `interval_ms` experienced on `link`.
#[derive(Debug, Clone, Serialize)]
pub struct LinkStats {
    pub packets: usize,
    pub delay_mean_ms: f64,
    pub delay_p50_ms: f64,
    pub delay_p99_ms: f64,
    /// Standard deviation of the one-way delay.
    pub jitter_ms: f64,
    pub loss_rate: f64,
    pub mean_loss_burst: f64,
    pub duplicates: usize,
    /// Packets that arrived after a later-sent one.
    pub reorders: usize,
}

/// What the profile promises, beside what [`measure`] found.
#[derive(Debug, Clone, Serialize)]
pub struct Expected {
    pub delay_mean_ms: f64,
    pub jitter_ms: f64,
    pub loss_rate: f64,
    pub mean_loss_burst: f64,
}

/// A profile's packets measured against the profile.
#[derive(Debug, Clone, Serialize)]
pub struct LinkReport {
    pub profile: Profile,
    pub packets: usize,
    pub interval_ms: f64,
    pub seed: u64,
    pub model: LinkModel,
    pub measured: LinkStats,
    pub expected: Expected,
}

impl LinkReport {
    /// Sends `packets` 100-byte packets, one every `interval_ms`, through
    /// `profile`'s link seeded with `seed`.
    pub fn measure(profile: Profile, packets: usize, interval_ms: f64, seed: u64) -> LinkReport {
        let model = LinkModel::profile(profile);
        let expected = Expected {
            delay_mean_ms: model.expected_delay(),
            jitter_ms: model.expected_jitter(),
            loss_rate: model.expected_loss(),
            mean_loss_burst: model.expected_burst(),
        };
        let mut link = Link::new(model.clone(), seed);
        LinkReport {
            profile,
            packets,
            interval_ms,
            seed,
            measured: measure(&mut link, packets, interval_ms, 100),
            model,
            expected,
        }
    }
}

/// Sends `packets` packets of `bytes` every `interval_ms` and measures.
pub fn measure(link: &mut Link, packets: usize, interval_ms: f64, bytes: usize) -> LinkStats {
    let mut arrivals: Vec<(f64, usize)> = Vec::new();
    let mut delays = Vec::new();
    let mut lost = vec![false; packets];
    let mut duplicates = 0;
    for (i, lost_i) in lost.iter_mut().enumerate() {
        let sent = i as f64 * interval_ms;
        let copies = link.send(sent, bytes);
        *lost_i = copies.is_empty();
        duplicates += copies.len().saturating_sub(1);
        for (k, &at) in copies.iter().enumerate() {
            if k == 0 {
                delays.push(at - sent);
            }
            arrivals.push((at, i));
        }
    }
    arrivals.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut highest = None;
    let mut reorders = 0;
    for &(_, seq) in &arrivals {
        match highest {
            Some(h) if seq < h => reorders += 1,
            _ => highest = Some(seq),
        }
    }
    let bursts: Vec<usize> = lost
        .split(|l| !l)
        .map(<[bool]>::len)
        .filter(|&n| n > 0)
        .collect();
    let n = delays.len().max(1) as f64;
    let mean = delays.iter().sum::<f64>() / n;
    let jitter = (delays.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n).sqrt();
    let mut sorted = delays.clone();
    sorted.sort_by(f64::total_cmp);
    let quantile = |q: f64| {
        sorted
            .get(((q * sorted.len() as f64) as usize).min(sorted.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f64::NAN)
    };
    LinkStats {
        packets,
        delay_mean_ms: mean,
        delay_p50_ms: quantile(0.5),
        delay_p99_ms: quantile(0.99),
        jitter_ms: jitter,
        loss_rate: lost.iter().filter(|&&l| l).count() as f64 / packets.max(1) as f64,
        mean_loss_burst: if bursts.is_empty() {
            0.0
        } else {
            bursts.iter().sum::<usize>() as f64 / bursts.len() as f64
        },
        duplicates,
        reorders,
    }
}

impl Report for LinkReport {
    fn table(&self) -> Table {
        let (m, e) = (&self.measured, &self.expected);
        let mut table = Table::columns(&["", "measured", "profile"]).title(format!(
            "{}: {} packets, one every {} ms, seed {}",
            self.profile, self.packets, self.interval_ms, self.seed
        ));
        let rows = [
            ("delay mean, ms", m.delay_mean_ms, Some(e.delay_mean_ms)),
            ("jitter (sd), ms", m.jitter_ms, Some(e.jitter_ms)),
            (
                "loss rate, %",
                m.loss_rate * 100.0,
                Some(e.loss_rate * 100.0),
            ),
            ("loss burst", m.mean_loss_burst, Some(e.mean_loss_burst)),
            ("delay p50, ms", m.delay_p50_ms, None),
            ("delay p99, ms", m.delay_p99_ms, None),
        ];
        for (name, got, want) in rows {
            table.row(vec![
                name.to_owned(),
                format!("{got:.4}"),
                want.map_or(String::new(), |w| format!("{w:.4}")),
            ]);
        }
        table.row(vec![
            "duplicates".into(),
            m.duplicates.to_string(),
            String::new(),
        ]);
        table.row(vec![
            "reorders".into(),
            m.reorders.to_string(),
            String::new(),
        ]);
        table
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quantile_and_cdf_are_inverse() {
        for p in [0.001, 0.1, 0.5, 0.9, 0.999] {
            assert!((normal_cdf(normal_quantile(p)) - p).abs() < 1e-6);
        }
    }

    #[test]
    fn unknown_profiles_are_named() {
        let e = "dialup".parse::<Profile>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown link profile 'dialup' (known: lan, internet2, internet-2005, \
             intercontinental, congested, geo-satellite)"
        );
    }
}
