//! The overhead camera's model: how floor millimetres map to image pixels.
//!
//! A real lab's camera is never exactly overhead: it is tilted, off-centre,
//! its lens sits off the sensor's axis. Whatever its pose, a flat floor
//! appears through a homography, which calibration fits from floor points
//! whose pixels are known. The floor frame follows ROS map files: origin
//! bottom-left, x right, y up; images have rows going down. Pixel (c, r)
//! covers [c, c+1) × [r, r+1).

use serde::{Deserialize, Serialize};

use nalgebra::{DMatrix, DVector};

use crate::Point;
use crate::model::homography::{CalibrationError, Homography};
use crate::model::lens::{Distortion, LensError};
use vl_report::table::{Report, Table};

/// A camera: its image size and frame rate, and where each floor point
/// appears in its images.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(try_from = "CameraWire", into = "CameraWire")]
pub struct CameraModel {
    pub width_px: u32,
    pub height_px: u32,
    /// Frames per second the Host captures at.
    pub fps: f64,
    floor_to_image: Homography,
    image_to_floor: Homography,
    /// The lens's bending of the homography's ideal pixels.
    distortion: Distortion,
}

/// How a camera model travels: the map one way; the other is derived.
#[derive(Serialize, Deserialize, schemars::JsonSchema)]
struct CameraWire {
    width_px: u32,
    height_px: u32,
    fps: f64,
    /// Floor mm (x, y, 1) → image (column, row, 1) up to scale, row by row.
    floor_to_image: Homography,
    /// The lens's radial distortion, when it has any.
    #[serde(default, skip_serializing_if = "Distortion::is_none")]
    distortion: Distortion,
}

impl TryFrom<CameraWire> for CameraModel {
    type Error = CameraModelError;

    fn try_from(wire: CameraWire) -> Result<Self, CameraModelError> {
        if !(wire.fps.is_finite() && wire.fps >= 0.0) {
            return Err(CameraModelError::FrameRate(wire.fps));
        }
        if wire.width_px == 0 || wire.height_px == 0 {
            return Err(CameraModelError::NoPixels);
        }
        wire.distortion.check(wire.width_px, wire.height_px)?;
        Ok(
            CameraModel::new(wire.width_px, wire.height_px, wire.fps, wire.floor_to_image)
                .with_distortion(wire.distortion),
        )
    }
}

/// A camera model no camera has.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraModelError {
    #[error("a camera's frame rate must be zero or more, not {0}")]
    FrameRate(f64),
    #[error("a camera's image must have pixels")]
    NoPixels,
    #[error(transparent)]
    Lens(#[from] LensError),
}

impl From<CameraModel> for CameraWire {
    fn from(camera: CameraModel) -> Self {
        CameraWire {
            width_px: camera.width_px,
            height_px: camera.height_px,
            fps: camera.fps,
            floor_to_image: camera.floor_to_image,
            distortion: camera.distortion,
        }
    }
}

/// How well a calibration fits the points it was made from, px.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Reprojection {
    pub points: usize,
    pub rms_px: f64,
    pub max_px: f64,
}

/// A lab's camera as calibration found it: what `vl camera calibrate`
/// writes and `vl host --camera-calibration` reads.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Calibration {
    pub camera: CameraModel,
    /// None in a file written by hand: the camera is all it says.
    #[serde(default)]
    pub reprojection: Reprojection,
}

impl CameraModel {
    pub fn new(width_px: u32, height_px: u32, fps: f64, floor_to_image: Homography) -> CameraModel {
        CameraModel {
            width_px,
            height_px,
            fps,
            floor_to_image,
            image_to_floor: floor_to_image.inverse(),
            distortion: Distortion::default(),
        }
    }

    /// The same camera seen through a lens bending its image by `distortion`.
    pub fn with_distortion(self, distortion: Distortion) -> CameraModel {
        CameraModel { distortion, ..self }
    }

    pub fn distortion(&self) -> Distortion {
        self.distortion
    }

    /// A camera looking straight down at a `width_mm` × `height_mm` floor,
    /// seeing all of it across `width_px` columns.
    pub fn overhead(width_mm: f64, height_mm: f64, width_px: u32, fps: f64) -> CameraModel {
        let s = width_mm / f64::from(width_px);
        let height_px = (height_mm / s).ceil() as u32;
        let map = Homography::from_rows([
            [1.0 / s, 0.0, 0.0],
            [0.0, -1.0 / s, f64::from(height_px)],
            [0.0, 0.0, 1.0],
        ])
        .expect("a positive scale is invertible");
        CameraModel::new(width_px, height_px.max(1), fps, map)
    }

    /// A pinhole camera above the middle of a `width_mm` × `height_mm`
    /// floor, tilted `tilt_rad` from vertical towards +y (so the far side of
    /// the floor looks narrower), its focal length chosen so the floor
    /// fills a `width_px` × `height_px` image less a 2 % border.
    pub fn tilted(
        width_mm: f64,
        height_mm: f64,
        width_px: u32,
        height_px: u32,
        tilt_rad: f64,
        fps: f64,
    ) -> Result<CameraModel, CalibrationError> {
        if !(tilt_rad.is_finite() && tilt_rad.abs() < 1.2) {
            return Err(CalibrationError::FloorOutOfView(format!(
                "a tilt of {tilt_rad} rad does not look at the floor"
            )));
        }
        // Camera axes in floor coordinates: x along the floor's x, rows
        // going down the image (towards −y), the optical axis down and
        // forward; the camera stands back along that axis.
        let (s, c) = tilt_rad.sin_cos();
        let (ax, ay, az) = ([1.0, 0.0, 0.0], [0.0, -c, -s], [0.0, s, -c]);
        let distance = 1.5 * width_mm.hypot(height_mm);
        let centre = [
            width_mm / 2.0 - distance * az[0],
            height_mm / 2.0 - distance * az[1],
            -distance * az[2],
        ];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        // A floor point (x, y, 0) in camera coordinates: R·(p − centre).
        let t = [-dot(ax, centre), -dot(ay, centre), -dot(az, centre)];
        let unit = [
            [ax[0], ax[1], t[0]],
            [ay[0], ay[1], t[1]],
            [az[0], az[1], t[2]],
        ];
        let unit = Homography::from_rows(unit)?;
        // Fit the floor's image into the frame.
        let corners = [
            [0.0, 0.0],
            [width_mm, 0.0],
            [0.0, height_mm],
            [width_mm, height_mm],
        ]
        .map(|[x, y]| unit.apply(x, y));
        let lo = |i: usize| corners.iter().map(|p| p[i]).fold(f64::INFINITY, f64::min);
        let hi = |i: usize| {
            corners
                .iter()
                .map(|p| p[i])
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let (w, h) = (f64::from(width_px), f64::from(height_px));
        let f = (0.96 * w / (hi(0) - lo(0))).min(0.96 * h / (hi(1) - lo(1)));
        let (cx, cy) = (
            w / 2.0 - f * (lo(0) + hi(0)) / 2.0,
            h / 2.0 - f * (lo(1) + hi(1)) / 2.0,
        );
        let k = Homography::from_rows([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])?;
        Ok(CameraModel::new(width_px, height_px, fps, k.after(&unit)))
    }

    /// The camera whose map and lens best take each floor point of `pairs`
    /// to its pixel, and how far off its pixels are. The map is first
    /// fitted alone (the DLT), then map and lens together by
    /// Levenberg–Marquardt on the pixels' errors; a lens is fitted only
    /// from 8 pairs or more.
    pub fn calibrated(
        width_px: u32,
        height_px: u32,
        fps: f64,
        pairs: &[(Point, [f64; 2])],
    ) -> Result<Calibration, CalibrationError> {
        let linear = CameraModel::new(width_px, height_px, fps, Homography::fit(pairs)?);
        let camera = if pairs.len() >= 8 {
            refine(linear, pairs).unwrap_or(linear)
        } else {
            linear
        };
        let residuals: Vec<f64> = pairs
            .iter()
            .map(|&(p, [c, r])| {
                let (pc, pr) = camera.to_pixel(p);
                (pc - c).hypot(pr - r)
            })
            .collect();
        let n = residuals.len();
        let reprojection = Reprojection {
            points: n,
            rms_px: (residuals.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
            max_px: residuals.iter().copied().fold(0.0, f64::max),
        };
        Ok(Calibration {
            camera,
            reprojection,
        })
    }

    /// The same camera capturing at `fps`.
    pub fn at_fps(self, fps: f64) -> CameraModel {
        CameraModel { fps, ..self }
    }

    pub fn floor_to_image(&self) -> &Homography {
        &self.floor_to_image
    }

    /// Continuous image coordinates (column, row) of a floor point.
    pub fn to_pixel(&self, p: Point) -> (f64, f64) {
        let [c, r] = self.floor_to_image.apply(p.x_mm, p.y_mm);
        self.distortion.distort(self.width_px, self.height_px, c, r)
    }

    /// The floor point at continuous image coordinates (column, row).
    pub fn to_arena(&self, col: f64, row: f64) -> Point {
        let (c, r) = self
            .distortion
            .undistort(self.width_px, self.height_px, col, row);
        let [x_mm, y_mm] = self.image_to_floor.apply(c, r);
        Point { x_mm, y_mm }
    }

    /// The size of a pixel on the floor at the image's centre, mm: the
    /// scale for drawing and for choosing grid resolutions.
    pub fn mm_per_px(&self) -> f64 {
        let (c, r) = (
            f64::from(self.width_px) / 2.0,
            f64::from(self.height_px) / 2.0,
        );
        let o = self.to_arena(c, r);
        let right = self.to_arena(c + 1.0, r).distance(o);
        let down = self.to_arena(c, r + 1.0).distance(o);
        (right * down).sqrt()
    }

    /// Whether every point of a `width_mm` × `height_mm` floor falls inside
    /// the image, saying which corner does not.
    pub fn sees_floor(&self, width_mm: f64, height_mm: f64) -> Result<(), CalibrationError> {
        for (x, y) in [
            (0.0, 0.0),
            (width_mm, 0.0),
            (0.0, height_mm),
            (width_mm, height_mm),
        ] {
            let (c, r) = self.to_pixel(Point { x_mm: x, y_mm: y });
            let inside = (-0.5..=f64::from(self.width_px) + 0.5).contains(&c)
                && (-0.5..=f64::from(self.height_px) + 0.5).contains(&r);
            if !inside {
                return Err(CalibrationError::FloorOutOfView(format!(
                    "the floor's corner ({x:.0}, {y:.0}) mm appears at pixel ({c:.0}, {r:.0}), outside the {}×{} image",
                    self.width_px, self.height_px
                )));
            }
        }
        Ok(())
    }
}

/// Map and lens fitted together to `pairs`, from `start`: Levenberg–
/// Marquardt over the homography's eight free entries and k₁, k₂, with a
/// numerical Jacobian (each entry stepped by its own scale: the map's
/// perspective row is ten thousand times smaller than its others).
fn refine(start: CameraModel, pairs: &[(Point, [f64; 2])]) -> Option<CameraModel> {
    let (w, h) = (start.width_px, start.height_px);
    let rows = start.floor_to_image.rows();
    let last = rows[2][2];
    let model = |p: &[f64]| -> Option<CameraModel> {
        let map =
            Homography::from_rows([[p[0], p[1], p[2]], [p[3], p[4], p[5]], [p[6], p[7], last]])
                .ok()?;
        let lens = Distortion { k1: p[8], k2: p[9] };
        lens.check(w, h).ok()?;
        Some(CameraModel::new(w, h, start.fps, map).with_distortion(lens))
    };
    let residuals = |p: &[f64]| -> Option<DVector<f64>> {
        let camera = model(p)?;
        let mut e = DVector::zeros(2 * pairs.len());
        for (i, &(floor, [c, r])) in pairs.iter().enumerate() {
            let (pc, pr) = camera.to_pixel(floor);
            e[2 * i] = pc - c;
            e[2 * i + 1] = pr - r;
        }
        e.iter().all(|v| v.is_finite()).then_some(e)
    };
    let mut p = vec![
        rows[0][0], rows[0][1], rows[0][2], rows[1][0], rows[1][1], rows[1][2], rows[2][0],
        rows[2][1], 0.0, 0.0,
    ];
    let steps: Vec<f64> = p
        .iter()
        .enumerate()
        .map(|(i, v)| match i {
            8 | 9 => 1e-6,
            _ => (v.abs() * 1e-6).max(1e-12),
        })
        .collect();
    let mut error = residuals(&p)?;
    let mut cost = error.norm_squared();
    let mut lambda = 1e-3;
    for _ in 0..100 {
        let mut jacobian = DMatrix::zeros(error.len(), p.len());
        for j in 0..p.len() {
            let (mut up, mut down) = (p.clone(), p.clone());
            up[j] += steps[j];
            down[j] -= steps[j];
            let (Some(a), Some(b)) = (residuals(&up), residuals(&down)) else {
                return model(&p);
            };
            jacobian.set_column(j, &((a - b) / (2.0 * steps[j])));
        }
        let jtj = jacobian.transpose() * &jacobian;
        let gradient = jacobian.transpose() * &error;
        let mut improved = false;
        for _ in 0..10 {
            let mut damped = jtj.clone();
            for k in 0..p.len() {
                damped[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(delta) = damped.lu().solve(&(-&gradient)) else {
                lambda *= 10.0;
                continue;
            };
            let trial: Vec<f64> = p.iter().zip(delta.iter()).map(|(a, d)| a + d).collect();
            match residuals(&trial) {
                Some(e) if e.norm_squared() < cost => {
                    let gain = cost - e.norm_squared();
                    (p, error, cost) = (trial, e.clone(), e.norm_squared());
                    lambda = (lambda / 10.0).max(1e-12);
                    improved = gain > 1e-12 * cost.max(1e-12);
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    model(&p)
}

/// One known point of a points file (what `vl camera calibrate --points`
/// reads): where it is on the floor and where the image shows it.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct PointPair {
    pub floor_mm: [f64; 2],
    pub pixel: [f64; 2],
}

impl From<PointPair> for (Point, [f64; 2]) {
    fn from(p: PointPair) -> Self {
        let [x_mm, y_mm] = p.floor_mm;
        (Point { x_mm, y_mm }, p.pixel)
    }
}

impl Report for Calibration {
    fn table(&self) -> Table {
        let camera = &self.camera;
        let fit = &self.reprojection;
        let rows = vec![
            (
                "image",
                format!(
                    "{} × {} px at {} fps",
                    camera.width_px, camera.height_px, camera.fps
                ),
            ),
            ("points", fit.points.to_string()),
            ("reprojection rms", format!("{:.3} px", fit.rms_px)),
            ("reprojection max", format!("{:.3} px", fit.max_px)),
            (
                "scale at the centre",
                format!("{:.3} mm per px", camera.mm_per_px()),
            ),
            (
                "lens distortion",
                format!(
                    "k1 {:+.4}, k2 {:+.4}",
                    camera.distortion().k1,
                    camera.distortion().k2
                ),
            ),
        ];
        Table::pairs(rows).title("camera calibration")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points through a lens of known distortion: map and lens are fitted
    /// back, exactly from exact points.
    #[test]
    fn calibration_fits_the_lens_from_exact_points() {
        let truth = CameraModel::overhead(800.0, 600.0, 640, 15.0).with_distortion(Distortion {
            k1: -0.12,
            k2: 0.08,
        });
        let pairs: Vec<(Point, [f64; 2])> = (0..13)
            .flat_map(|i| (0..10).map(move |j| (i, j)))
            .map(|(i, j)| {
                let p = Point {
                    x_mm: 32.0 + 61.3 * f64::from(i),
                    y_mm: 24.0 + 61.3 * f64::from(j),
                };
                let (c, r) = truth.to_pixel(p);
                (p, [c, r])
            })
            .collect();
        let mut seed = 7u64;
        let noisy: Vec<(Point, [f64; 2])> = pairs
            .iter()
            .map(|&(p, [c, r])| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let a = ((seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.15;
                let b = ((seed >> 13 & 0xFFFF) as f64 / 65536.0 - 0.5) * 0.15;
                (p, [c + a, r + b])
            })
            .collect();
        // Centres found to a few hundredths of a pixel still give the lens
        // within a few per cent.
        let rough = CameraModel::calibrated(640, 480, 15.0, &noisy)
            .unwrap()
            .camera
            .distortion();
        assert!(
            (rough.k1 + 0.12).abs() < 0.005 && (rough.k2 - 0.08).abs() < 0.005,
            "{rough:?}"
        );
        let fit = CameraModel::calibrated(640, 480, 15.0, &pairs).unwrap();
        let lens = fit.camera.distortion();
        assert!(
            (lens.k1 + 0.12).abs() < 1e-4 && (lens.k2 - 0.08).abs() < 1e-4,
            "{lens:?}"
        );
        assert!(fit.reprojection.max_px < 1e-3, "{:?}", fit.reprojection);
    }

    #[test]
    fn pixel_centres_follow_the_ros_convention() {
        let cam = CameraModel::overhead(800.0, 600.0, 320, 10.0);
        assert_eq!((cam.width_px, cam.height_px), (320, 240));
        assert!((cam.mm_per_px() - 2.5).abs() < 1e-12);
        let centre = cam.to_arena(0.5, 239.5);
        assert!((centre.x_mm - 1.25).abs() < 1e-9 && (centre.y_mm - 1.25).abs() < 1e-9);
        let (c, r) = cam.to_pixel(centre);
        assert!((c - 0.5).abs() < 1e-9 && (r - 239.5).abs() < 1e-9);
    }

    #[test]
    fn a_tilted_camera_sees_the_far_side_smaller_and_the_whole_floor() {
        let cam = CameraModel::tilted(800.0, 600.0, 640, 480, 0.35, 15.0).unwrap();
        cam.sees_floor(800.0, 600.0).unwrap();
        let width_at = |y| {
            let (a, _) = cam.to_pixel(Point { x_mm: 0.0, y_mm: y });
            let (b, _) = cam.to_pixel(Point {
                x_mm: 800.0,
                y_mm: y,
            });
            b - a
        };
        assert!(
            width_at(600.0) < 0.9 * width_at(0.0),
            "{} {}",
            width_at(600.0),
            width_at(0.0)
        );
        // The far side is at the top of the image.
        let (_, near) = cam.to_pixel(Point {
            x_mm: 400.0,
            y_mm: 0.0,
        });
        let (_, far) = cam.to_pixel(Point {
            x_mm: 400.0,
            y_mm: 600.0,
        });
        assert!(far < near);
        let straight = CameraModel::tilted(800.0, 600.0, 640, 480, 0.0, 15.0).unwrap();
        let (a, _) = straight.to_pixel(Point {
            x_mm: 0.0,
            y_mm: 0.0,
        });
        let (b, _) = straight.to_pixel(Point {
            x_mm: 0.0,
            y_mm: 600.0,
        });
        assert!(
            (a - b).abs() < 1e-9,
            "untilted: parallel edges stay parallel"
        );
        assert!(CameraModel::tilted(800.0, 600.0, 640, 480, f64::NAN, 15.0).is_err());
    }

    #[test]
    fn the_wire_carries_one_map_and_rebuilds_the_other() {
        let cam = CameraModel::tilted(800.0, 600.0, 640, 480, 0.3, 15.0).unwrap();
        let json = serde_json::to_string(&cam).unwrap();
        assert!(json.contains("floor_to_image"), "{json}");
        let back: CameraModel = serde_json::from_str(&json).unwrap();
        let p = Point {
            x_mm: 123.0,
            y_mm: 456.0,
        };
        let (c, r) = back.to_pixel(p);
        let q = back.to_arena(c, r);
        assert!(q.distance(p) < 1e-6);
        let bad = json.replace("\"fps\":15.0", "\"fps\":-1.0");
        assert!(serde_json::from_str::<CameraModel>(&bad).is_err());
    }

    #[test]
    fn calibration_recovers_a_camera_from_its_points() {
        let truth = CameraModel::tilted(800.0, 600.0, 640, 480, 0.4, 15.0).unwrap();
        let pairs: Vec<_> = (0..5)
            .flat_map(|i| {
                (0..4).map(move |j| Point {
                    x_mm: 80.0 + 160.0 * f64::from(i),
                    y_mm: 60.0 + 160.0 * f64::from(j),
                })
            })
            .map(|p| {
                let (c, r) = truth.to_pixel(p);
                (p, [c, r])
            })
            .collect();
        let Calibration {
            camera: fitted,
            reprojection: fit,
        } = CameraModel::calibrated(640, 480, 15.0, &pairs).unwrap();
        assert!(fit.max_px < 1e-6, "{fit:?}");
        let (c, r) = fitted.to_pixel(Point {
            x_mm: 5.0,
            y_mm: 595.0,
        });
        let (c0, r0) = truth.to_pixel(Point {
            x_mm: 5.0,
            y_mm: 595.0,
        });
        assert!((c - c0).hypot(r - r0) < 1e-6);
    }
}
