//! The overhead camera: renders the arena and the robot, seen from above.

use image::{Rgb, RgbImage};
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use vl_core::{Arena, CameraModel, Point};

use crate::noise::gaussian;
use crate::world::World;

const FLOOR: Rgb<u8> = Rgb([226, 224, 216]);
const BODY: Rgb<u8> = Rgb([170, 36, 32]);
/// A light disc on the front half of the body shows the heading.
const MARKER: Rgb<u8> = Rgb([250, 250, 250]);

/// How the simulated camera departs from an ideal one. All zero (the
/// default) renders the ideal image; with any of them the frame is still
/// a pure function of the world and the seed.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Optics {
    /// Shift of the image, px (columns right, rows down), as when the lens
    /// sits off the sensor's axis; lab staff calibrate it away.
    pub lens_offset_px: [f64; 2],
    /// Gaussian blur, standard deviation in px.
    pub blur_px: f64,
    /// Per-pixel Gaussian noise, standard deviation in grey levels.
    pub noise: f64,
    /// How much darker the bottom-right corner is than the top-left one
    /// (0 to 1), as under a single lamp.
    pub lighting_gradient: f64,
    /// Seed of the noise; each frame also mixes in the virtual time.
    pub seed: u64,
}

impl Optics {
    /// Whether the options make sense, naming the one that does not.
    pub fn check(&self) -> Result<(), String> {
        let [dx, dy] = self.lens_offset_px;
        if !(dx.is_finite() && dy.is_finite()) {
            return Err("the lens offset must be finite".into());
        }
        for (what, v) in [("blur", self.blur_px), ("noise", self.noise)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("the camera {what} must be zero or more, not {v}"));
            }
        }
        if !(0.0..=1.0).contains(&self.lighting_gradient) {
            return Err(format!(
                "the lighting gradient must be between 0 and 1, not {}",
                self.lighting_gradient
            ));
        }
        Ok(())
    }
}

/// A camera that sees the whole arena at `width_px` columns.
pub fn camera_for(world: &World, width_px: u32, fps: f64) -> CameraModel {
    let arena = world.arena();
    CameraModel::overhead(arena.width_mm, arena.height_mm, width_px, fps)
}

impl World {
    /// The overhead camera's view of the arena and the robot now. Each shape
    /// is painted over its own bounding box only, so a frame costs about one
    /// pass over the image whatever the arena holds.
    pub fn render(&self, camera: &CameraModel, optics: &Optics) -> RgbImage {
        let arena = self.arena();
        let robot = self.robot();
        let pose = self.pose();
        let [dx, dy] = optics.lens_offset_px;
        // The camera shifted by the lens offset sees these arena points.
        let sample =
            |c: u32, r: u32| camera.to_arena(f64::from(c) + 0.5 - dx, f64::from(r) + 0.5 - dy);
        let shifted = |p: Point| Point {
            x_mm: p.x_mm + dx * camera.mm_per_px,
            y_mm: p.y_mm - dy * camera.mm_per_px,
        };
        let mut image = RgbImage::from_pixel(camera.width_px, camera.height_px, FLOOR);
        paint_walls(&mut image, camera, arena, optics.lens_offset_px);
        for obstacle in &arena.obstacles {
            let (lo, hi) = obstacle.shape.bounds();
            let colour = Rgb(obstacle.material.colour);
            paint(
                &mut image,
                camera,
                (shifted(lo), shifted(hi)),
                &sample,
                |p| (obstacle.shape.distance(p) <= 0.0).then_some(colour),
            );
        }
        let marker = pose.to_world(robot.radius_mm * 0.45, 0.0);
        let marker_r = robot.radius_mm * 0.35;
        let r = robot.radius_mm;
        let body = (
            shifted(Point {
                x_mm: pose.x_mm - r,
                y_mm: pose.y_mm - r,
            }),
            shifted(Point {
                x_mm: pose.x_mm + r,
                y_mm: pose.y_mm + r,
            }),
        );
        paint(&mut image, camera, body, &sample, |p| {
            if p.distance(marker) <= marker_r {
                Some(MARKER)
            } else {
                (p.distance(pose.point()) <= r).then_some(BODY)
            }
        });
        if optics.blur_px > 0.0 {
            blur(&mut image, optics.blur_px);
        }
        if optics.lighting_gradient > 0.0 || optics.noise > 0.0 {
            let seed = optics.seed ^ (self.time_s() * 1e3).round() as u64;
            shade(&mut image, optics, seed);
        }
        image
    }
}

/// Paints the walls' colour on the pixels whose centre, shifted by the
/// lens offset, lies beyond the floor: whole columns and rows, computed
/// rather than tested pixel by pixel.
fn paint_walls(image: &mut RgbImage, camera: &CameraModel, arena: &Arena, [dx, dy]: [f64; 2]) {
    let (w, h) = (camera.width_px, camera.height_px);
    // The first and one-past-last index in 0..n whose centre + shift lies in 0..=extent px.
    let span = |n: u32, shift: f64, extent: f64| {
        let first = (shift - 0.5).ceil().clamp(0.0, f64::from(n)) as u32;
        let end = ((extent + shift - 0.5).floor() + 1.0).clamp(0.0, f64::from(n)) as u32;
        (first, end.max(first))
    };
    // Pixel c sees x = (c + 0.5 − dx)·S; row r sees y = (H − r − 0.5 + dy)·S.
    let (c0, c1) = span(w, dx, arena.width_mm / camera.mm_per_px);
    let (r0, r1) = span(
        h,
        f64::from(h) - arena.height_mm / camera.mm_per_px + dy,
        arena.height_mm / camera.mm_per_px,
    );
    let walls = Rgb(arena.walls.colour);
    for r in 0..h {
        if (r0..r1).contains(&r) {
            for c in (0..c0).chain(c1..w) {
                image.put_pixel(c, r, walls);
            }
        } else {
            for c in 0..w {
                image.put_pixel(c, r, walls);
            }
        }
    }
}

/// Paints the pixels whose centre falls in `bounds` (mm) that `colour`
/// gives a colour; `sample` says which arena point a pixel sees.
fn paint(
    image: &mut RgbImage,
    camera: &CameraModel,
    (lo, hi): (Point, Point),
    sample: &impl Fn(u32, u32) -> Point,
    colour: impl Fn(Point) -> Option<Rgb<u8>>,
) {
    let (w, h) = (camera.width_px, camera.height_px);
    let (c0, r1) = camera.to_pixel(lo);
    let (c1, r0) = camera.to_pixel(hi);
    let clamp = |v: f64, max: u32| v.floor().clamp(0.0, f64::from(max)) as u32;
    let (cols, rows) = (
        clamp(c0, w)..clamp(c1 + 1.0, w),
        clamp(r0, h)..clamp(r1 + 1.0, h),
    );
    for r in rows {
        for c in cols.clone() {
            if let Some(colour) = colour(sample(c, r)) {
                image.put_pixel(c, r, colour);
            }
        }
    }
}

/// A separable Gaussian blur of standard deviation `sigma` px, edges clamped.
fn blur(image: &mut RgbImage, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as i64;
    let weights: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = weights.iter().sum();
    let (w, h) = (i64::from(image.width()), i64::from(image.height()));
    for (dc, dr) in [(1, 0), (0, 1)] {
        let source = image.clone();
        for r in 0..h {
            for c in 0..w {
                let mut acc = [0f32; 3];
                for (k, weight) in weights.iter().enumerate() {
                    let off = k as i64 - radius;
                    let sc = (c + off * dc).clamp(0, w - 1) as u32;
                    let sr = (r + off * dr).clamp(0, h - 1) as u32;
                    let px = source.get_pixel(sc, sr);
                    for ch in 0..3 {
                        acc[ch] += weight * f32::from(px[ch]);
                    }
                }
                let px = image.get_pixel_mut(c as u32, r as u32);
                for ch in 0..3 {
                    px[ch] = (acc[ch] / total).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

/// Darkens towards the bottom-right corner and adds per-pixel noise.
fn shade(image: &mut RgbImage, optics: &Optics, seed: u64) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let (w, h) = (f64::from(image.width()), f64::from(image.height()));
    for (c, r, px) in image.enumerate_pixels_mut() {
        let along = (f64::from(c) / w + f64::from(r) / h) / 2.0;
        let gain = 1.0 - optics.lighting_gradient * along;
        for ch in px.0.iter_mut() {
            let noise = if optics.noise > 0.0 {
                optics.noise * gaussian(&mut rng)
            } else {
                0.0
            };
            *ch = (f64::from(*ch) * gain + noise).round().clamp(0.0, 255.0) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Arena, RobotModel};

    #[test]
    fn the_robot_appears_where_it_is() {
        let w = World::new(Arena::navigation(), RobotModel::khepera_ii(), 0).unwrap();
        let cam = camera_for(&w, 320, 10.0);
        assert_eq!((cam.width_px, cam.height_px), (320, 240));
        let img = w.render(&cam, &Optics::default());
        let (c, r) = cam.to_pixel(w.pose().point());
        // Just behind the centre is body; in front of it, the heading marker.
        assert_eq!(*img.get_pixel(c as u32 - 8, r as u32), BODY);
        assert_eq!(*img.get_pixel(c as u32 + 6, r as u32), MARKER);
        // The box at x = 250..310, y = 0..230 is dark.
        let (bc, br) = cam.to_pixel(vl_core::Point {
            x_mm: 280.0,
            y_mm: 100.0,
        });
        assert_eq!(
            *img.get_pixel(bc as u32, br as u32),
            Rgb(w.arena().obstacles[0].material.colour)
        );
    }

    #[test]
    fn optics_are_deterministic_and_do_what_they_say() {
        let w = World::new(Arena::navigation(), RobotModel::khepera_ii(), 0).unwrap();
        let cam = camera_for(&w, 160, 10.0);
        let ideal = w.render(&cam, &Optics::default());
        let shifted = w.render(
            &cam,
            &Optics {
                lens_offset_px: [3.0, -2.0],
                ..Optics::default()
            },
        );
        assert_eq!(shifted.get_pixel(60 + 3, 80 - 2), ideal.get_pixel(60, 80));
        // The image moved right and up: walls show on the left and bottom.
        let walls = Rgb(w.arena().walls.colour);
        let (last_col, last_row) = (cam.width_px - 1, cam.height_px - 1);
        assert_eq!(*shifted.get_pixel(2, 60), walls);
        assert_ne!(*shifted.get_pixel(3, 60), walls);
        assert_eq!(*shifted.get_pixel(80, last_row - 1), walls);
        assert_ne!(*shifted.get_pixel(80, last_row - 2), walls);
        assert_ne!(*shifted.get_pixel(last_col, 0), walls);
        let noisy = |seed| {
            w.render(
                &cam,
                &Optics {
                    blur_px: 1.0,
                    noise: 4.0,
                    lighting_gradient: 0.3,
                    seed,
                    ..Optics::default()
                },
            )
        };
        assert_eq!(noisy(1), noisy(1));
        assert_ne!(noisy(1), noisy(2));
        let lit = noisy(1);
        // The floor is darker towards the bottom-right corner.
        let grey = |c, r| f64::from(lit.get_pixel(c, r).0[1]);
        assert!(
            grey(5, 5) > grey(150, 112) + 40.0,
            "{} {}",
            grey(5, 5),
            grey(150, 112)
        );
        // Blur leaves the box's edge in between floor and obstacle.
        let sharp = w.render(
            &cam,
            &Optics {
                blur_px: 1.5,
                ..Optics::default()
            },
        );
        let (c, r) = cam.to_pixel(Point {
            x_mm: 250.0,
            y_mm: 100.0,
        });
        let edge = sharp.get_pixel(c as u32, r as u32).0[1];
        assert!((70..200).contains(&edge), "{edge}");
        assert!(
            Optics {
                lighting_gradient: 2.0,
                ..Optics::default()
            }
            .check()
            .is_err()
        );
        assert!(
            Optics {
                blur_px: -1.0,
                ..Optics::default()
            }
            .check()
            .is_err()
        );
    }
}
