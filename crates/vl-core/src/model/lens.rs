//! A lens's radial distortion (Brown's model with two terms): a cheap
//! webcam's wide lens bends straight lines outwards towards the image's
//! corners (barrel distortion, k₁ < 0), by a dozen pixels or more. A
//! pixel at distance r from the image's centre appears at
//! r·(1 + k₁r² + k₂r⁴), with r measured in image widths (about a webcam's
//! focal length in pixels, so k₁ and k₂ read as usual).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The two radial terms; both zero is a perfect lens.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
}

/// Largest |k₁| or |k₂| a lens may have: beyond it, no webcam.
const MAX_K: f64 = 2.0;

/// Why two terms are no lens's.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LensError {
    #[error("a lens's k1 and k2 are finite and within ±{MAX_K}, not {k1} and {k2}")]
    OutOfRange { k1: f64, k2: f64 },
    #[error("a lens with k1 = {k1} and k2 = {k2} folds the image's corners over")]
    Folds { k1: f64, k2: f64 },
}

impl Distortion {
    pub fn is_none(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0
    }

    /// How much a point `r2` (squared radius, image widths²) from the
    /// centre is pushed outwards: its radius is multiplied by this.
    fn factor(&self, r2: f64) -> f64 {
        1.0 + self.k1 * r2 + self.k2 * r2 * r2
    }

    /// Where the ideal pixel (c, r) of a `width` × `height` image appears
    /// through the lens.
    pub fn distort(&self, width: u32, height: u32, c: f64, r: f64) -> (f64, f64) {
        if self.is_none() {
            return (c, r);
        }
        let (cx, cy, f) = centre(width, height);
        let (x, y) = ((c - cx) / f, (r - cy) / f);
        let k = self.factor(x * x + y * y);
        (cx + f * x * k, cy + f * y * k)
    }

    /// The ideal pixel the lens shows at (c, r): the inverse of
    /// [`Distortion::distort`], by Newton's method on the radius.
    pub fn undistort(&self, width: u32, height: u32, c: f64, r: f64) -> (f64, f64) {
        if self.is_none() {
            return (c, r);
        }
        let (cx, cy, f) = centre(width, height);
        let (x, y) = ((c - cx) / f, (r - cy) / f);
        let seen = x.hypot(y);
        if seen < 1e-12 {
            return (c, r);
        }
        // Solve u·(1 + k₁u² + k₂u⁴) = seen for the ideal radius u.
        let mut u = seen;
        for _ in 0..8 {
            let u2 = u * u;
            let g = u * self.factor(u2) - seen;
            let slope = 1.0 + 3.0 * self.k1 * u2 + 5.0 * self.k2 * u2 * u2;
            if slope.abs() < 1e-9 {
                break;
            }
            let step = g / slope;
            u -= step;
            if step.abs() < 1e-12 {
                break;
            }
        }
        let scale = u / seen;
        (cx + f * x * scale, cy + f * y * scale)
    }

    /// Whether this is a lens: finite, bounded, and bending every radius
    /// out to the image's corners one way (no fold, which would show a
    /// point twice).
    pub fn check(&self, width: u32, height: u32) -> Result<(), LensError> {
        let (k1, k2) = (self.k1, self.k2);
        if !(k1.is_finite() && k2.is_finite()) || k1.abs() > MAX_K || k2.abs() > MAX_K {
            return Err(LensError::OutOfRange { k1, k2 });
        }
        let (cx, cy, f) = centre(width, height);
        let corner = cx.hypot(cy) / f * 1.2;
        for i in 0..=100 {
            let u2 = (corner * f64::from(i) / 100.0).powi(2);
            if 1.0 + 3.0 * k1 * u2 + 5.0 * k2 * u2 * u2 <= 0.0 {
                return Err(LensError::Folds { k1, k2 });
            }
        }
        Ok(())
    }
}

/// The image's centre and the unit radii are measured in, px.
fn centre(width: u32, height: u32) -> (f64, f64, f64) {
    (
        f64::from(width) / 2.0,
        f64::from(height) / 2.0,
        f64::from(width.max(1)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Undistorting what the lens shows gives the ideal pixel back,
        /// anywhere in the image, for any lens that does not fold.
        #[test]
        fn undistort_inverts_distort(
            k1 in -0.4f64..0.4, k2 in -0.2f64..0.2,
            c in 0.0f64..640.0, r in 0.0f64..480.0,
        ) {
            let lens = Distortion { k1, k2 };
            prop_assume!(lens.check(640, 480).is_ok());
            let (dc, dr) = lens.distort(640, 480, c, r);
            let (uc, ur) = lens.undistort(640, 480, dc, dr);
            prop_assert!((uc - c).abs() < 1e-6 && (ur - r).abs() < 1e-6, "({c}, {r}) → ({dc}, {dr}) → ({uc}, {ur})");
        }
    }

    #[test]
    fn barrel_distortion_pulls_the_corners_in() {
        let lens = Distortion { k1: -0.15, k2: 0.0 };
        let (c, r) = lens.distort(640, 480, 0.0, 0.0);
        assert!(c > 10.0 && r > 5.0, "({c}, {r})");
        assert_eq!(lens.distort(640, 480, 320.0, 240.0), (320.0, 240.0));
        assert!(
            Distortion {
                k1: f64::NAN,
                k2: 0.0
            }
            .check(640, 480)
            .is_err()
        );
        let e = Distortion { k1: -1.5, k2: 0.0 }
            .check(640, 480)
            .unwrap_err();
        assert!(e.to_string().contains("folds"), "{e}");
    }
}
