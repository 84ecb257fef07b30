//! Speed controller characterisation (thesis C.2): a robot's measured step
//! responses fitted with the [`SpeedResponse`] law — the gain from where
//! each step settles, the time constant and dead time from small steps
//! (which the acceleration limit does not touch), the acceleration limit
//! from a large one.

use serde::Serialize;
use thiserror::Error;
use vl_report::table::{Report, Table, count};

use crate::SpeedResponse;

/// One step of the speed command and what the wheels did.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The speed before the step, which the wheels had settled on, mm/s.
    pub from_mm_s: f64,
    /// The commanded speed, mm/s.
    pub to_mm_s: f64,
    /// (seconds since the command, measured speed in mm/s).
    pub samples: Vec<(f64, f64)>,
}

/// The fitted law and how well it fits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Fit {
    pub response: SpeedResponse,
    /// Root mean square of the residuals over every sample, mm/s.
    pub rms_mm_s: f64,
    pub samples: usize,
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum FitError {
    #[error("no step to a non-zero speed to read the gain from")]
    NoGain,
    #[error("too few samples ({0}) to fit a response")]
    TooFew(usize),
}

/// Fits the law to `small` steps (within the acceleration limit) and
/// `large` ones (beyond it; may be empty, leaving the default limit).
pub fn fit_response(small: &[Step], large: &[Step]) -> Result<Fit, FitError> {
    let count: usize = small.iter().map(|s| s.samples.len()).sum();
    if count < 10 {
        return Err(FitError::TooFew(count));
    }
    if !small
        .iter()
        .any(|s| s.to_mm_s.abs() > 1e-9 && !s.samples.is_empty())
    {
        return Err(FitError::NoGain);
    }
    // A first-order rise after the dead time: for each time constant and
    // dead time the best gain is a linear least-squares solution; the pair
    // is found by a coarse then a fine search.
    let rise = |tau: f64, dead: f64| {
        let fall = |t: f64| {
            if t <= dead {
                1.0
            } else {
                (-(t - dead) / tau).exp()
            }
        };
        let (mut num, mut den) = (0.0, 0.0);
        for s in small {
            for &(t, v) in &s.samples {
                let e = fall(t);
                let lever = s.to_mm_s * (1.0 - e);
                num += (v - s.from_mm_s * e) * lever;
                den += lever * lever;
            }
        }
        let gain = if den > 0.0 { num / den } else { 1.0 };
        let sse: f64 = small
            .iter()
            .flat_map(|s| {
                s.samples.iter().map(move |&(t, v)| {
                    let e = fall(t);
                    (v - s.from_mm_s * e - gain * s.to_mm_s * (1.0 - e)).powi(2)
                })
            })
            .sum();
        (sse, gain)
    };
    let rise_sse = |tau: f64, dead: f64| rise(tau, dead).0;
    // A controller that acts at its own period may move within that
    // period of the command: the curve then leads, and the dead time the
    // search may find is negative (reported as none).
    let (mut tau, mut dead) = best_of(
        (1..=300).map(|ms| f64::from(ms) * 1e-3),
        (-10..=60).map(|ms| f64::from(ms) * 1e-3),
        rise_sse,
    );
    (tau, dead) = best_of(
        (-20..=20).map(|k| (tau + f64::from(k) * 5e-5).max(1e-4)),
        (-20..=20).map(|k| dead + f64::from(k) * 5e-5),
        rise_sse,
    );
    let gain = rise(tau, dead).1;
    let dead = dead.max(0.0);
    let mut response = SpeedResponse {
        gain,
        time_constant_s: tau,
        dead_time_s: dead,
        ..SpeedResponse::default()
    };
    if !large.is_empty() {
        let accel_sse = |a: f64| {
            let r = SpeedResponse {
                max_accel_mm_s2: a,
                ..response
            };
            large.iter().map(|s| simulated_sse(&r, s)).sum::<f64>()
        };
        // Log-spaced from 100 mm/s² to 100 m/s², then refined.
        let coarse = (0..=300).map(|k| 100.0 * 10f64.powf(f64::from(k) / 100.0));
        let a = coarse.min_by(|x, y| accel_sse(*x).total_cmp(&accel_sse(*y)));
        let a = a.expect("a non-empty range");
        let fine = (-50..=50).map(|k| a * (1.0 + f64::from(k) * 1e-3));
        response.max_accel_mm_s2 = fine
            .min_by(|x, y| accel_sse(*x).total_cmp(&accel_sse(*y)))
            .expect("a non-empty range");
    }
    let sse: f64 = small
        .iter()
        .chain(large)
        .map(|s| simulated_sse(&response, s))
        .sum();
    let samples = count + large.iter().map(|s| s.samples.len()).sum::<usize>();
    Ok(Fit {
        response,
        rms_mm_s: (sse / samples as f64).sqrt(),
        samples,
    })
}

/// The pair of `taus` × `deads` with the least `sse`.
fn best_of(
    taus: impl Iterator<Item = f64> + Clone,
    deads: impl Iterator<Item = f64> + Clone,
    sse: impl Fn(f64, f64) -> f64,
) -> (f64, f64) {
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for tau in taus {
        for dead in deads.clone() {
            let e = sse(tau, dead);
            if e < best.0 {
                best = (e, tau, dead);
            }
        }
    }
    (best.1, best.2)
}

/// Squared residuals of `step` against the law `r` stepped finely from
/// the command on.
fn simulated_sse(r: &SpeedResponse, step: &Step) -> f64 {
    const DT: f64 = 2e-4;
    let (mut t, mut v, mut sse) = (0.0, step.from_mm_s, 0.0);
    for &(at, measured) in &step.samples {
        while t + DT <= at {
            let command = if t < r.dead_time_s {
                step.from_mm_s / r.gain.max(1e-9)
            } else {
                step.to_mm_s
            };
            v = r.step(v, command, DT);
            t += DT;
        }
        sse += (measured - v).powi(2);
    }
    sse
}

impl Report for Fit {
    fn table(&self) -> Table {
        let r = self.response;
        Table::pairs([
            ("gain", format!("{:.3}", r.gain)),
            (
                "time constant",
                format!("{:.1} ms", r.time_constant_s * 1e3),
            ),
            ("acceleration", format!("{:.0} mm/s²", r.max_accel_mm_s2)),
            ("dead time", format!("{:.1} ms", r.dead_time_s * 1e3)),
            (
                "fit",
                format!(
                    "{:.1} mm/s RMS over {}",
                    self.rms_mm_s,
                    count(self.samples as u64, "sample", "samples")
                ),
            ),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Steps as `truth` answers them, sampled every `every_s` with speeds
    /// rounded to `quantum` (a Khepera reports whole pulses per 10 ms).
    fn measured(truth: &SpeedResponse, from: f64, to: f64, every_s: f64, quantum: f64) -> Step {
        let (mut t, mut v, dt) = (0.0, from * truth.gain, 1e-5);
        let mut samples = Vec::new();
        let mut next = every_s / 2.0;
        while t < 0.5 {
            let command = if t < truth.dead_time_s { from } else { to };
            v = truth.step(v, command, dt);
            t += dt;
            if t >= next {
                samples.push((t, (v / quantum).round() * quantum));
                next += every_s;
            }
        }
        Step {
            from_mm_s: from * truth.gain,
            to_mm_s: to,
            samples,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// The fit recovers the law it was measured from, quantised like
        /// a Khepera's readings.
        #[test]
        fn recovers_the_law_it_was_measured_from(
            gain in 0.9f64..1.1,
            tau in 0.01f64..0.1,
            accel in 2000.0f64..8000.0,
            dead in 0.0f64..0.02,
        ) {
            let truth = SpeedResponse { gain, time_constant_s: tau, max_accel_mm_s2: accel, dead_time_s: dead };
            // Small steps stay under the limit: the first 2 ms change is below a·2 ms.
            let small_to = (accel * tau * 0.5).min(200.0);
            let small = [
                measured(&truth, 0.0, small_to, 0.002, 1.0),
                measured(&truth, small_to, 0.0, 0.002, 1.0),
                measured(&truth, 0.0, -small_to, 0.002, 1.0),
            ];
            let large = [measured(&truth, 0.0, 800.0, 0.002, 1.0)];
            let fit = fit_response(&small, &large).unwrap();
            let r = fit.response;
            // A plateau read in whole pulses is off by up to half a pulse
            // in every sample: no fit can know the gain better than that.
            let resolution = 0.5 / small_to;
            prop_assert!((r.gain - gain).abs() < 0.02 * gain + resolution, "{:?}", r);
            // Nor the time constant: half a pulse on a rise a(1 - e^(-t/τ))
            // moves τ by up to e·τ·(0.5 / a), where the rise is steepest in τ.
            let tau_resolution = std::f64::consts::E * tau * resolution / gain;
            prop_assert!((r.time_constant_s - tau).abs() < 0.05 * tau + 5e-4 + tau_resolution, "{:?}", r);
            prop_assert!((r.dead_time_s - dead).abs() < 2e-3, "{:?}", r);
            prop_assert!((r.max_accel_mm_s2 - accel).abs() < 0.1 * accel, "{:?}", r);
        }
    }

    #[test]
    fn nothing_to_fit_is_said() {
        assert_eq!(fit_response(&[], &[]), Err(FitError::TooFew(0)));
        let flat = Step {
            from_mm_s: 0.0,
            to_mm_s: 0.0,
            samples: (0..20).map(|i| (f64::from(i) * 0.01, 0.0)).collect(),
        };
        assert_eq!(fit_response(&[flat], &[]), Err(FitError::NoGain));
    }
}
