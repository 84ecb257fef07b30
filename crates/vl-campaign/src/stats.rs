//! What a figure over seeds is worth: its mean and the 95 % confidence
//! interval of that mean (Student's t, the seeds' spread), so a reader sees
//! whether two cells differ or only their seeds do.

use serde::Serialize;

/// Student's t at 97.5 % for 1 … 30 degrees of freedom; beyond, the normal's.
const T_975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];
const Z_975: f64 = 1.960;

/// A mean over `n` values and the half width of its 95 % interval (none
/// of one value: a single seed says nothing of the spread).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    pub mean: f64,
    pub half: Option<f64>,
    pub n: usize,
}

impl Interval {
    /// The interval of the finite `values`; none when there are none.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Interval> {
        let v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        let n = v.len();
        if n == 0 {
            return None;
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let half = (n > 1).then(|| {
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let t = T_975.get(n - 2).copied().unwrap_or(Z_975);
            t * (var / n as f64).sqrt()
        });
        Some(Interval { mean, half, n })
    }

    pub fn low(&self) -> f64 {
        self.mean - self.half.unwrap_or(0.0)
    }

    pub fn high(&self) -> f64 {
        self.mean + self.half.unwrap_or(0.0)
    }

    /// Whether the two intervals leave each other apart: a difference the
    /// seeds' spread does not explain.
    pub fn apart(&self, other: &Interval) -> bool {
        self.half.is_some()
            && other.half.is_some()
            && (self.high() < other.low() || other.high() < self.low())
    }

    /// "12.3 ± 1.4" with `decimals`, or "12.3" of one value.
    pub fn text(&self, decimals: usize) -> String {
        match self.half {
            Some(h) => format!("{:.*} ± {:.*}", decimals, self.mean, decimals, h),
            None => format!("{:.*}", decimals, self.mean),
        }
    }

    /// [`Interval::text`] of `i`, a dash of none.
    pub fn cell(i: Option<Interval>, decimals: usize) -> String {
        i.map_or("–".into(), |i| i.text(decimals))
    }
}

#[cfg(test)]
mod tests {
    use super::Interval;
    use proptest::prelude::*;

    #[test]
    fn five_seeds_use_students_t() {
        let i = Interval::of([10.0, 12.0, 11.0, 13.0, 9.0]).unwrap();
        assert_eq!(i.mean, 11.0);
        // s = 1.581, t(4) = 2.776: 2.776 · 1.581 / √5 = 1.963.
        assert!((i.half.unwrap() - 1.963).abs() < 1e-3, "{i:?}");
        assert_eq!(i.text(1), "11.0 ± 2.0");
        assert_eq!(Interval::of([4.0]).unwrap().half, None);
        assert_eq!(Interval::of([f64::NAN]), None);
    }

    proptest! {
        #[test]
        fn the_interval_holds_its_mean_and_narrows_with_agreement(
            values in prop::collection::vec(-1e6f64..1e6, 1..60),
        ) {
            let i = Interval::of(values.iter().copied()).unwrap();
            prop_assert_eq!(i.n, values.len());
            prop_assert!(i.low() <= i.mean && i.mean <= i.high());
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            prop_assert!(lo - 1e-6 <= i.mean && i.mean <= hi + 1e-6);
            // Every seed agreeing: no spread to explain.
            let same = Interval::of(values.iter().map(|_| values[0])).unwrap();
            prop_assert!(same.half.unwrap_or(0.0) < 1e-6 * values[0].abs().max(1.0));
            prop_assert!(!same.apart(&same));
        }
    }
}
