//! Natural cubic splines through knots, parameterised by accumulated chord
//! length: the parameter grows with the distance between knots, so the
//! curve does not bunch up or overshoot where knots are close together.

/// A point the spline passes through: x, y and a third coordinate (the
/// heading scaled to mm, or 0 for a robot whose heading does not matter).
pub(crate) type Knot = [f64; 3];

/// A natural cubic spline (zero curvature at both ends) in three coordinates.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Spline {
    /// Chord-length parameter of each knot; starts at 0.
    t: Vec<f64>,
    knots: Vec<Knot>,
    /// Second derivative at each knot, per coordinate.
    curvature: Vec<Knot>,
}

impl Spline {
    /// The spline through `knots`, in order. Repeated consecutive knots are
    /// merged; a single knot gives a spline of length 0.
    pub(crate) fn through(knots: &[Knot]) -> Spline {
        let mut kept: Vec<Knot> = Vec::with_capacity(knots.len());
        let mut t = Vec::with_capacity(knots.len());
        for &k in knots {
            match kept.last() {
                None => t.push(0.0),
                Some(last) => {
                    let chord = distance(last, &k);
                    if chord <= 1e-9 {
                        continue;
                    }
                    t.push(t.last().copied().unwrap_or(0.0) + chord);
                }
            }
            kept.push(k);
        }
        let curvature = natural_curvature(&t, &kept);
        Spline {
            t,
            knots: kept,
            curvature,
        }
    }

    /// Total chord length, which is the parameter's range.
    #[cfg(test)]
    fn chord_length(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0)
    }

    /// The knot interval holding parameter `t`.
    pub(crate) fn interval(&self, t: f64) -> usize {
        let n = self.t.len();
        if n < 2 {
            return 0;
        }
        self.t.partition_point(|&ti| ti <= t).clamp(1, n - 1) - 1
    }

    /// The point at parameter `t` (clamped to the ends).
    #[cfg(test)]
    fn at(&self, t: f64) -> Knot {
        if self.knots.len() < 2 {
            return self.knots.first().copied().unwrap_or_default();
        }
        let t = t.clamp(0.0, self.chord_length());
        self.on(self.interval(t), t)
    }

    /// The point at parameter `t` on the cubic of interval `i`.
    fn on(&self, i: usize, t: f64) -> Knot {
        let h = self.t[i + 1] - self.t[i];
        let a = (self.t[i + 1] - t) / h;
        let b = 1.0 - a;
        let (ca, cb) = ((a * a * a - a) * h * h / 6.0, (b * b * b - b) * h * h / 6.0);
        let (y0, y1) = (&self.knots[i], &self.knots[i + 1]);
        let (m0, m1) = (&self.curvature[i], &self.curvature[i + 1]);
        std::array::from_fn(|d| a * y0[d] + b * y1[d] + ca * m0[d] + cb * m1[d])
    }

    /// Points at most `step` apart (straight-line distance), both ends
    /// included, each with its parameter. Uniform in the parameter within
    /// each interval, then halved wherever the curve runs faster than its
    /// chord.
    pub(crate) fn sample(&self, step: f64) -> Vec<(f64, Knot)> {
        self.sample_intervals(0..self.intervals(), step)
    }

    /// The number of intervals between knots.
    pub(crate) fn intervals(&self) -> usize {
        self.knots.len().saturating_sub(1)
    }

    /// The part of [`Self::sample`] that falls in `intervals`, after their
    /// first knot (which the part before ends with) unless they start the
    /// spline: parts taken over adjoining ranges join into the whole.
    pub(crate) fn sample_intervals(
        &self,
        intervals: std::ops::Range<usize>,
        step: f64,
    ) -> Vec<(f64, Knot)> {
        let Some(&first) = self.knots.first() else {
            return Vec::new();
        };
        let mut out = Vec::with_capacity(
            ((self.t[intervals.end.max(intervals.start)] - self.t[intervals.start]) / step)
                as usize
                + 2,
        );
        let mut previous = if intervals.start == 0 {
            out.push((0.0, first));
            if self.knots.len() == 1 {
                out.push((0.0, first));
            }
            (0.0, first)
        } else {
            // As the interval before ends it, to the last bit.
            let t = self.t[intervals.start];
            (t, self.on(intervals.start - 1, t))
        };
        for i in intervals {
            let (t0, t1) = (self.t[i], self.t[i + 1]);
            let n = ((t1 - t0) / step).ceil().max(1.0) as usize;
            for j in 1..=n {
                let t = if j == n {
                    t1
                } else {
                    t0 + (t1 - t0) * j as f64 / n as f64
                };
                let next = (t, self.on(i, t));
                self.fill(i, previous, next, step, &mut out, 0);
                out.push(next);
                previous = next;
            }
        }
        out
    }

    /// Pushes points of interval `i` between `a` and `b` (exclusive) until
    /// none are more than `step` apart.
    fn fill(
        &self,
        i: usize,
        a: (f64, Knot),
        b: (f64, Knot),
        step: f64,
        out: &mut Vec<(f64, Knot)>,
        depth: u32,
    ) {
        if distance(&a.1, &b.1) <= step || depth > 20 {
            return;
        }
        let t = (a.0 + b.0) / 2.0;
        let mid = (t, self.on(i, t));
        self.fill(i, a, mid, step, out, depth + 1);
        out.push(mid);
        self.fill(i, mid, b, step, out, depth + 1);
    }

    /// The parameter of knot `i`.
    #[cfg(test)]
    fn knot_t(&self, i: usize) -> f64 {
        self.t[i]
    }
}

fn distance(a: &Knot, b: &Knot) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Second derivatives of the natural spline: the tridiagonal system of the
/// continuity conditions, solved by the Thomas algorithm.
fn natural_curvature(t: &[f64], y: &[Knot]) -> Vec<Knot> {
    let n = t.len();
    let mut m = vec![[0.0; 3]; n];
    if n < 3 {
        return m;
    }
    // Unknowns m[1..n-1]; row i: h[i-1] m[i-1] + 2(h[i-1]+h[i]) m[i] + h[i] m[i+1] = rhs.
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mut diag = vec![0.0; n];
    let mut rhs = vec![[0.0; 3]; n];
    for i in 1..n - 1 {
        diag[i] = 2.0 * (h[i - 1] + h[i]);
        rhs[i] = std::array::from_fn(|d| {
            6.0 * ((y[i + 1][d] - y[i][d]) / h[i] - (y[i][d] - y[i - 1][d]) / h[i - 1])
        });
    }
    for i in 2..n - 1 {
        let f = h[i - 1] / diag[i - 1];
        diag[i] -= f * h[i - 1];
        let above = rhs[i - 1];
        for (r, a) in rhs[i].iter_mut().zip(above) {
            *r -= f * a;
        }
    }
    for i in (1..n - 1).rev() {
        m[i] = std::array::from_fn(|d| (rhs[i][d] - h[i] * m[i + 1][d]) / diag[i]);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_through_its_knots_and_is_straight_for_collinear_ones() {
        let knots = [
            [0.0, 0.0, 0.0],
            [10.0, 5.0, 0.0],
            [30.0, -2.0, 0.0],
            [31.0, 8.0, 0.0],
        ];
        let s = Spline::through(&knots);
        for (i, k) in knots.iter().enumerate() {
            let p = s.at(s.knot_t(i));
            assert!(distance(&p, k) < 1e-9, "{p:?} vs {k:?}");
        }
        let line = Spline::through(&[[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [3.0, 3.0, 0.0]]);
        for (_, p) in line.sample(0.1) {
            assert!((p[0] - p[1]).abs() < 1e-9);
        }
    }

    #[test]
    fn two_knots_give_the_chord_and_repeats_merge() {
        let s = Spline::through(&[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [4.0, 3.0, 0.0]]);
        assert_eq!(s.chord_length(), 5.0);
        assert_eq!(s.at(2.5), [2.0, 1.5, 0.0]);
        assert_eq!(Spline::through(&[[1.0, 2.0, 0.0]]).sample(1.0).len(), 2);
    }
}
