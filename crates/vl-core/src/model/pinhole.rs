//! The lab's camera as a pinhole above the floor: its intrinsics, where it
//! stands and which way it looks, and its lens as OpenCV's plumb bob — what
//! Foxglove's `CameraCalibration` (and ROS's `CameraInfo`) need to place
//! the image in 3D. The lab keeps its camera as a floor-to-image
//! homography; this is that homography taken apart (Zhang's constraints on
//! one plane), with the principal point at the image's centre, where the
//! lens model is centred too.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::CameraModel;

/// The camera as a pinhole: `pixel ~ K·(R·floor + t)`, floor in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    pub width_px: u32,
    pub height_px: u32,
    /// Focal length, px.
    pub f_px: f64,
    pub cx_px: f64,
    pub cy_px: f64,
    /// Where the camera's centre is in the arena, mm (z up from the floor).
    pub position_mm: [f64; 3],
    /// The camera's axes in the arena's frame (x right in the image, y
    /// down it, z along the optical axis), as a rotation.
    pub orientation: UnitQuaternion<f64>,
    /// OpenCV's plumb-bob terms (k1, k2, p1, p2, k3).
    pub plumb_bob: [f64; 5],
}

impl Pinhole {
    /// Where a floor point (mm) shows, in ideal (undistorted) pixels.
    pub fn to_pixel(&self, x_mm: f64, y_mm: f64) -> Option<(f64, f64)> {
        let position = Vector3::from(self.position_mm);
        let seen = self.orientation.inverse() * (Vector3::new(x_mm, y_mm, 0.0) - position);
        (seen.z > 1e-9).then(|| {
            (
                self.cx_px + self.f_px * seen.x / seen.z,
                self.cy_px + self.f_px * seen.y / seen.z,
            )
        })
    }

    /// The intrinsic matrix, row-major.
    pub fn k(&self) -> [f64; 9] {
        let (f, cx, cy) = (self.f_px, self.cx_px, self.cy_px);
        [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]
    }

    /// The projection matrix of a single camera, row-major.
    pub fn p(&self) -> [f64; 12] {
        let (f, cx, cy) = (self.f_px, self.cx_px, self.cy_px);
        [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    }
}

impl CameraModel {
    /// This camera as a pinhole. A camera looking straight down gives no
    /// focal length (a nearer camera with a wider lens sees the same): it
    /// is taken as the image's width, a webcam's 53° across.
    pub fn pinhole(&self) -> Pinhole {
        let (w, h) = (f64::from(self.width_px), f64::from(self.height_px));
        let (cx, cy) = (w / 2.0, h / 2.0);
        let rows = self.floor_to_image().rows();
        let map = Matrix3::from_fn(|r, c| rows[r][c]);
        // The homography with the principal point moved to the origin:
        // diag(f, f, 1)·λ[r1 r2 t].
        let shift = Matrix3::new(1.0, 0.0, -cx, 0.0, 1.0, -cy, 0.0, 0.0, 1.0);
        let a = shift * map;
        let f = focal_length(&a, w).unwrap_or(w);
        let unfocus = Matrix3::new(1.0 / f, 0.0, 0.0, 0.0, 1.0 / f, 0.0, 0.0, 0.0, 1.0);
        let b = unfocus * a;
        let (b1, b2, b3) = (b.column(0), b.column(1), b.column(2));
        let mut scale = 2.0 / (b1.norm() + b2.norm());
        // The floor is in front of the camera.
        if b3.z * scale < 0.0 {
            scale = -scale;
        }
        let (r1, r2) = (b1 * scale, b2 * scale);
        let t = b3 * scale;
        let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
        // The nearest rotation (the columns are orthonormal only up to
        // the fit's noise).
        let svd = r.svd(true, true);
        let (u, v_t) = (svd.u.expect("asked for"), svd.v_t.expect("asked for"));
        let mut rotation = u * v_t;
        if rotation.determinant() < 0.0 {
            rotation = -rotation;
        }
        // camera = R·floor + t: the camera's centre and axes in the arena.
        let to_arena = rotation.transpose();
        let centre = -(to_arena * t);
        let orientation =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(to_arena));
        // The lens model counts radii in image widths; OpenCV's in focal lengths.
        let d = self.distortion();
        let ratio = (f / w).powi(2);
        Pinhole {
            width_px: self.width_px,
            height_px: self.height_px,
            f_px: f,
            cx_px: cx,
            cy_px: cy,
            position_mm: [centre.x, centre.y, centre.z],
            orientation,
            plumb_bob: [d.k1 * ratio, d.k2 * ratio * ratio, 0.0, 0.0, 0.0],
        }
    }
}

/// The focal length that makes `a`'s first two columns (after dividing
/// their x and y by it) orthogonal and of one length, when the view is
/// oblique enough to tell; within 0.2–20 image widths.
fn focal_length(a: &Matrix3<f64>, width: f64) -> Option<f64> {
    let (a1, a2) = (a.column(0), a.column(1));
    let plausible = |f2: f64| {
        let f = f2.sqrt();
        (f2.is_finite() && f > 0.2 * width && f < 20.0 * width).then_some(f)
    };
    let orthogonal = a1.z * a2.z;
    let equal = a2.z * a2.z - a1.z * a1.z;
    let scale = a1.norm() * a2.norm();
    let by_orthogonality = (orthogonal.abs() > 1e-9 * scale)
        .then(|| -(a1.x * a2.x + a1.y * a2.y) / orthogonal)
        .and_then(plausible);
    let by_length = (equal.abs() > 1e-9 * scale)
        .then(|| (a1.x * a1.x + a1.y * a1.y - a2.x * a2.x - a2.y * a2.y) / equal)
        .and_then(plausible);
    match (by_orthogonality, by_length) {
        (Some(a), Some(b)) => Some((a + b) / 2.0),
        (a, b) => a.or(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Point;
    use proptest::prelude::*;

    /// The largest distance, px, between where the camera model and its
    /// pinhole put the floor's points.
    fn worst_px(camera: &CameraModel, width_mm: f64, height_mm: f64) -> f64 {
        let pinhole = camera.pinhole();
        let ideal = (*camera).with_distortion(crate::Distortion::default());
        let mut worst: f64 = 0.0;
        for i in 0..=10 {
            for j in 0..=10 {
                let p = Point {
                    x_mm: width_mm * f64::from(i) / 10.0,
                    y_mm: height_mm * f64::from(j) / 10.0,
                };
                let (c, r) = ideal.to_pixel(p);
                let (pc, pr) = pinhole.to_pixel(p.x_mm, p.y_mm).expect("in front");
                worst = worst.max((c - pc).hypot(r - pr));
            }
        }
        worst
    }

    #[test]
    fn an_overhead_camera_looks_straight_down_from_above_the_middle() {
        let camera = CameraModel::overhead(800.0, 600.0, 640, 15.0);
        let pinhole = camera.pinhole();
        let [x, y, z] = pinhole.position_mm;
        assert!(
            (x - 400.0).abs() < 1e-6 && (y - 300.0).abs() < 1e-6,
            "{x} {y}"
        );
        assert!(
            (z - 800.0).abs() < 1e-6,
            "its height is the floor's width: {z}"
        );
        let down = pinhole.orientation * Vector3::z();
        assert!(
            (down - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-9,
            "{down}"
        );
        assert!(worst_px(&camera, 800.0, 600.0) < 1e-6);
    }

    proptest! {
        /// A tilted camera's pinhole shows the floor where the camera
        /// model does, within a pixel, and stands above the floor.
        #[test]
        fn a_tilted_camera_comes_apart_into_a_pinhole_that_shows_the_same_floor(
            tilt in -0.6f64..0.6,
            width_mm in 300.0f64..2000.0,
            aspect in 0.5f64..1.5,
        ) {
            let height_mm = width_mm * aspect;
            let camera = CameraModel::tilted(width_mm, height_mm, 640, 480, tilt, 15.0).unwrap();
            prop_assert!(camera.pinhole().position_mm[2] > 0.0);
            let worst = worst_px(&camera, width_mm, height_mm);
            prop_assert!(worst < 1.0, "{worst} px off");
        }
    }
}
