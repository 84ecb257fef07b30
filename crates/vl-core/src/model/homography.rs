//! Plane-to-plane projective maps: how the floor's millimetres appear in a
//! camera's pixels whatever the camera's height, tilt or lens offset, and
//! the direct linear transform (DLT) that fits one to point pairs.

use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use thiserror::Error;

use crate::Point;

/// Why no map could be fitted or made.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CalibrationError {
    #[error("a calibration needs at least 4 point pairs, got {0}")]
    TooFewPoints(usize),
    #[error("point pair {0} is not made of finite numbers")]
    NotFinite(usize),
    #[error(
        "the points do not fix a camera: three or more of them lie on one line, or they repeat"
    )]
    Degenerate,
    #[error("the map is not invertible: it folds the floor onto a line")]
    Singular,
    #[error("the map's matrix holds a number that is not finite")]
    NotFiniteMatrix,
    #[error("the camera does not see the whole floor: {0}")]
    FloorOutOfView(String),
    #[error("calibration target: {0}")]
    Target(String),
}

/// A projective map of the plane: (x, y) ↦ ((h₀₀x + h₀₁y + h₀₂)/w, (h₁₀x +
/// h₁₁y + h₁₂)/w) with w = h₂₀x + h₂₁y + h₂₂. On the wire, its 3 × 3 matrix
/// row by row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography(Matrix3<f64>);

impl Homography {
    /// The map with matrix `rows`, if it is finite and invertible.
    pub fn from_rows(rows: [[f64; 3]; 3]) -> Result<Homography, CalibrationError> {
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CalibrationError::NotFiniteMatrix);
        }
        let m = Matrix3::from_fn(|r, c| rows[r][c]);
        Homography::from_matrix(m)
    }

    /// Scaled so its last entry is 1 (the usual form, and a readable one
    /// on the wire), unless that entry is 0.
    fn from_matrix(m: Matrix3<f64>) -> Result<Homography, CalibrationError> {
        let largest = m.abs().max();
        if !(largest.is_finite() && largest > 0.0) {
            return Err(CalibrationError::Singular);
        }
        if (m / largest).determinant().abs() < 1e-15 {
            return Err(CalibrationError::Singular);
        }
        let last = m[(2, 2)];
        let scale = if last.abs() > 1e-9 * largest {
            last
        } else {
            largest
        };
        Ok(Homography(m / scale))
    }

    pub fn rows(&self) -> [[f64; 3]; 3] {
        let m = &self.0;
        [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ]
    }

    /// Where the map takes (x, y).
    pub fn apply(&self, x: f64, y: f64) -> [f64; 2] {
        let v = self.0 * Vector3::new(x, y, 1.0);
        [v.x / v.z, v.y / v.z]
    }

    pub fn inverse(&self) -> Homography {
        // Invertible by construction.
        let inverse = self.0.try_inverse().unwrap_or_else(Matrix3::identity);
        Homography::from_matrix(inverse).unwrap_or(*self)
    }

    /// `self` after `first`.
    pub fn after(&self, first: &Homography) -> Homography {
        // Both invertible: so is the product.
        Homography::from_matrix(self.0 * first.0).unwrap_or(*self)
    }

    /// Fits the map that takes each `from` to its `to` (at least four pairs,
    /// no three of the first four on a line), by the normalised DLT: both
    /// point sets are centred and scaled, the 2n × 9 system solved by SVD,
    /// and the normalisation undone.
    pub fn fit(pairs: &[(Point, [f64; 2])]) -> Result<Homography, CalibrationError> {
        if pairs.len() < 4 {
            return Err(CalibrationError::TooFewPoints(pairs.len()));
        }
        for (i, (p, q)) in pairs.iter().enumerate() {
            if ![p.x_mm, p.y_mm, q[0], q[1]].iter().all(|v| v.is_finite()) {
                return Err(CalibrationError::NotFinite(i));
            }
        }
        let from = normaliser(pairs.iter().map(|(p, _)| [p.x_mm, p.y_mm]))?;
        let to = normaliser(pairs.iter().map(|(_, q)| *q))?;
        // At least nine rows, so the SVD yields all nine right singular vectors.
        let rows = (2 * pairs.len()).max(9);
        let mut a = DMatrix::<f64>::zeros(rows, 9);
        for (i, (p, q)) in pairs.iter().enumerate() {
            let [x, y] = from.apply(p.x_mm, p.y_mm);
            let [u, v] = to.apply(q[0], q[1]);
            let r = 2 * i;
            a.row_mut(r)
                .copy_from_slice(&[-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]);
            a.row_mut(r + 1)
                .copy_from_slice(&[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]);
        }
        let svd = a.svd(false, true);
        let v_t = svd.v_t.ok_or(CalibrationError::Degenerate)?;
        let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
        order.sort_by(|&i, &j| svd.singular_values[i].total_cmp(&svd.singular_values[j]));
        // One null direction: the map. A second one means the points leave
        // the map undetermined (collinear or repeated).
        let (least, next) = (svd.singular_values[order[0]], svd.singular_values[order[1]]);
        let largest = svd.singular_values[order[order.len() - 1]];
        if next <= 1e-9 * largest || !least.is_finite() {
            return Err(CalibrationError::Degenerate);
        }
        let h = v_t.row(order[0]);
        let normalised = Matrix3::from_fn(|r, c| h[3 * r + c]);
        let m = to.inverse().0 * normalised * from.0;
        let fitted = Homography::from_matrix(m).map_err(|_| CalibrationError::Degenerate)?;
        // Three collinear points among four leave a map that folds the
        // plane; it shows as points sent to infinity or far off.
        if pairs.iter().any(|(p, q)| {
            let [u, v] = fitted.apply(p.x_mm, p.y_mm);
            !(u.is_finite() && v.is_finite()) || (u - q[0]).hypot(v - q[1]) > 1e6
        }) {
            return Err(CalibrationError::Degenerate);
        }
        Ok(fitted)
    }

    /// Distance from where the map takes each pair's first point to its
    /// second, in the second's units.
    pub fn residuals(&self, pairs: &[(Point, [f64; 2])]) -> Vec<f64> {
        pairs
            .iter()
            .map(|(p, q)| {
                let [u, v] = self.apply(p.x_mm, p.y_mm);
                (u - q[0]).hypot(v - q[1])
            })
            .collect()
    }
}

/// The similarity that centres `points` on the origin with a mean distance
/// of √2 from it (Hartley's normalisation).
fn normaliser(
    points: impl Iterator<Item = [f64; 2]> + Clone,
) -> Result<Homography, CalibrationError> {
    let n = points.clone().count() as f64;
    let (sx, sy) = points
        .clone()
        .fold((0.0, 0.0), |(sx, sy), [x, y]| (sx + x, sy + y));
    let (cx, cy) = (sx / n, sy / n);
    let spread = points.map(|[x, y]| (x - cx).hypot(y - cy)).sum::<f64>() / n;
    if !(spread.is_finite() && spread > 0.0) {
        return Err(CalibrationError::Degenerate);
    }
    let s = std::f64::consts::SQRT_2 / spread;
    Ok(Homography(Matrix3::new(
        s,
        0.0,
        -s * cx,
        0.0,
        s,
        -s * cy,
        0.0,
        0.0,
        1.0,
    )))
}

impl Serialize for Homography {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.rows().serialize(serializer)
    }
}

/// As serialised: three rows of three.
impl schemars::JsonSchema for Homography {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Homography".into()
    }

    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        <[[f64; 3]; 3]>::json_schema(generator)
    }
}

impl<'de> Deserialize<'de> for Homography {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let rows = <[[f64; 3]; 3]>::deserialize(deserializer)?;
        Homography::from_rows(rows).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn p(x_mm: f64, y_mm: f64) -> Point {
        Point { x_mm, y_mm }
    }

    /// A camera looking at the floor from a random place: a random
    /// invertible projective map that keeps an 800 × 600 mm floor in front.
    fn camera() -> impl Strategy<Value = Homography> {
        (
            0.3f64..3.0,
            -0.5f64..0.5,
            -0.3f64..0.3,
            -200.0f64..200.0,
            -200.0f64..200.0,
            -4e-4f64..4e-4,
            -4e-4f64..4e-4,
        )
            .prop_map(|(s, rot, shear, tx, ty, g, h)| {
                Homography::from_rows([
                    [s * rot.cos(), -s * rot.sin() + shear, tx + 300.0],
                    [s * rot.sin(), -s * rot.cos(), ty + 400.0],
                    [g, h, 1.0],
                ])
                .unwrap()
            })
    }

    proptest! {
        /// From four or more exact pairs the fit is the map itself.
        #[test]
        fn exact_pairs_give_the_map_back(truth in camera(), points in prop::collection::vec((0.0f64..800.0, 0.0f64..600.0), 4..20)) {
            let points: Vec<Point> = points.into_iter().map(|(x, y)| p(x, y)).collect();
            let pairs: Vec<_> = points.iter().map(|&q| (q, truth.apply(q.x_mm, q.y_mm))).collect();
            match Homography::fit(&pairs) {
                Ok(fitted) => {
                    for x in [0.0, 400.0, 800.0] {
                        for y in [0.0, 300.0, 600.0] {
                            let [a, b] = fitted.apply(x, y);
                            let [c, d] = truth.apply(x, y);
                            // Random points may sit nearly on a line: the
                            // farther from them, the less the map is fixed.
                            prop_assert!((a - c).hypot(b - d) < 1e-3 * (1.0 + c.abs() + d.abs()), "{a} {b} vs {c} {d}");
                        }
                    }
                }
                Err(CalibrationError::Degenerate) => {}
                Err(e) => prop_assert!(false, "{e}"),
            }
        }

        /// The inverse undoes the map.
        #[test]
        fn the_inverse_undoes(truth in camera(), x in 0.0f64..800.0, y in 0.0f64..600.0) {
            let [u, v] = truth.apply(x, y);
            let [a, b] = truth.inverse().apply(u, v);
            prop_assert!((a - x).abs() < 1e-6 && (b - y).abs() < 1e-6);
        }
    }

    #[test]
    fn too_few_collinear_and_broken_points_are_refused() {
        let square = [p(0.0, 0.0), p(100.0, 0.0), p(100.0, 100.0), p(0.0, 100.0)];
        let pairs: Vec<_> = square.iter().map(|&q| (q, [q.x_mm, q.y_mm])).collect();
        assert_eq!(
            Homography::fit(&pairs[..3]),
            Err(CalibrationError::TooFewPoints(3))
        );
        let line: Vec<_> = (0..5)
            .map(|i| {
                let x = f64::from(i) * 10.0;
                (p(x, 2.0 * x), [x, x])
            })
            .collect();
        assert_eq!(Homography::fit(&line), Err(CalibrationError::Degenerate));
        let mut nan = pairs.clone();
        nan[2].1 = [f64::NAN, 0.0];
        assert_eq!(Homography::fit(&nan), Err(CalibrationError::NotFinite(2)));
        assert!(
            Homography::from_rows([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).is_err()
        );
        let json = serde_json::to_string(&Homography::fit(&pairs).unwrap()).unwrap();
        let back: Homography = serde_json::from_str(&json).unwrap();
        assert!(back.residuals(&pairs).iter().all(|&e| e < 1e-9));
        assert!(serde_json::from_str::<Homography>("[[0,0,0],[0,0,0],[0,0,0]]").is_err());
    }
}
