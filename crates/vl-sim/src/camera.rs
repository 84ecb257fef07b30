//! The overhead camera: renders the arena and the robot, seen from above.

use image::{Rgb, RgbImage};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use vl_core::{Calibration, CalibrationError, CameraModel, DotTarget, Point, Shape};

use crate::optics::{Optics, add_noise, blur, finish, light};
use crate::world::World;

const FLOOR: Rgb<u8> = Rgb([226, 224, 216]);
const BODY: Rgb<u8> = Rgb([170, 36, 32]);
/// A light disc on the front half of the body shows the heading.
const MARKER: Rgb<u8> = Rgb([250, 250, 250]);
/// A hand held over the robot: lighter than the camera's threshold, so the
/// robot vanishes into the floor.
const HAND: Rgb<u8> = Rgb([214, 176, 150]);

/// A camera that sees the whole arena at `width_px` columns.
pub fn camera_for(world: &World, width_px: u32, fps: f64) -> CameraModel {
    let arena = world.arena();
    CameraModel::overhead(arena.width_mm, arena.height_mm, width_px, fps)
}

impl World {
    /// The overhead camera's view of the arena and the robot now (one
    /// frame; a [`Renderer`] makes many faster).
    pub fn render(&self, camera: &CameraModel, optics: &Optics) -> RgbImage {
        Renderer::new(*camera, *optics).render(self)
    }

    /// One frame `width_px` wide from a camera straight above: of the
    /// arena and the robot, or of a calibration `target` laid on its empty
    /// floor; with the camera that took it (`vl sim render`).
    pub fn overhead_view(
        &self,
        width_px: u32,
        optics: &Optics,
        target: Option<&DotTarget>,
    ) -> (RgbImage, CameraModel) {
        let camera = camera_for(self, width_px.max(1), 15.0);
        let arena = self.arena();
        let image = match target {
            Some(target) => render_target(target, &camera, optics, arena.width_mm, arena.height_mm),
            None => self.render(&camera, optics),
        };
        (image, camera)
    }
}

/// A camera's frames of a world. What does not move — floor, walls and
/// obstacles, blurred and lit as the optics say — is drawn once for each
/// layout of the arena and copied; each frame then draws only the robot's
/// patch over it (smeared over the exposure, its marker sometimes partly
/// hidden) and the sensor's noise over all.
#[derive(Debug, Clone)]
pub struct Renderer {
    nominal: CameraModel,
    optics: Optics,
    backdrop: Option<Backdrop>,
}

#[derive(Debug, Clone)]
struct Backdrop {
    /// The arena's obstacles when it was drawn: people only add some.
    obstacles: usize,
    /// Before the lens's blur and the lamp.
    sharp: RgbImage,
    finished: RgbImage,
}

/// Poses a moving robot is drawn at over one exposure.
const EXPOSURE_POSES: usize = 5;
/// A cable across the marker, as something that hides part of it.
const CABLE: Rgb<u8> = Rgb([48, 46, 44]);

impl Renderer {
    pub fn new(nominal: CameraModel, optics: Optics) -> Renderer {
        Renderer {
            nominal,
            optics,
            backdrop: None,
        }
    }

    pub fn optics(&self) -> &Optics {
        &self.optics
    }

    /// The frame the camera takes of `world` now.
    pub fn render(&mut self, world: &World) -> RgbImage {
        let arena = world.arena();
        let optics = self.optics;
        let camera = optics.view(&self.nominal, arena.width_mm, arena.height_mm);
        let stale = self
            .backdrop
            .as_ref()
            .is_none_or(|b| b.obstacles != arena.obstacles.len());
        if stale {
            let sharp = still_scene(world, &camera, &optics);
            let mut finished = sharp.clone();
            if optics.blur_px > 0.0 {
                blur(&mut finished, optics.blur_px);
            }
            light(
                &mut finished,
                &optics,
                (0, 0),
                (camera.width_px, camera.height_px),
            );
            self.backdrop = Some(Backdrop {
                obstacles: arena.obstacles.len(),
                sharp,
                finished,
            });
        }
        let backdrop = self.backdrop.as_ref().expect("drawn above");
        let mut image = backdrop.finished.clone();
        draw_robot(&mut image, &backdrop.sharp, world, &camera, &optics);
        if optics.noise > 0.0 {
            let seed = optics.seed ^ (world.time_s() * 1e3).round() as u64;
            add_noise(&mut image, &optics, seed);
        }
        image
    }
}

/// The floor, walls and obstacles, sharp.
fn still_scene(world: &World, camera: &CameraModel, optics: &Optics) -> RgbImage {
    let arena = world.arena();
    let mut image = floor_and_walls(
        camera,
        optics,
        arena.width_mm,
        arena.height_mm,
        Rgb(arena.walls.colour),
    );
    for obstacle in &arena.obstacles {
        let colour = Rgb(obstacle.material.colour);
        paint(&mut image, camera, optics, obstacle.shape.bounds(), |p| {
            (obstacle.shape.distance(p) <= 0.0).then_some(colour)
        });
    }
    image
}

/// Draws the robot over `image`: each pixel of its patch the mean of what
/// it sees at each pose of the exposure (the robot's colour where the body
/// is, `sharp`'s still scene elsewhere), then blurred and lit as the rest.
fn draw_robot(
    image: &mut RgbImage,
    sharp: &RgbImage,
    world: &World,
    camera: &CameraModel,
    optics: &Optics,
) {
    let robot = world.robot();
    let (r, now) = (robot.radius_mm, world.pose());
    // Back over the exposure along the wheels' motion.
    let wheels = world.wheels();
    let moving = optics.exposure_s > 0.0 && wheels != vl_core::WheelSpeeds::default();
    let poses: Vec<vl_core::Pose> = if moving {
        (0..EXPOSURE_POSES)
            .map(|k| {
                let back = optics.exposure_s * k as f64 / (EXPOSURE_POSES - 1) as f64;
                now.advance(wheels, robot.wheel_base_mm, -back)
            })
            .collect()
    } else {
        vec![now]
    };
    let covered = world.robot_covered();
    let mut rng =
        Pcg64Mcg::seed_from_u64(optics.seed ^ 0xCAB1E ^ (world.time_s() * 1e3).round() as u64);
    let cable = (optics.occlusion_rate > 0.0 && rng.random::<f64>() < optics.occlusion_rate)
        .then(|| rng.random_range(0.0..std::f64::consts::PI));
    let marker_r = r * 0.35;
    let colour_at = |pose: &vl_core::Pose, p: Point| -> Option<Rgb<u8>> {
        let marker = pose.to_world(r * 0.45, 0.0);
        if p.distance(pose.point()) > r {
            return None;
        }
        if covered {
            return Some(HAND);
        }
        if let Some(angle) = cable {
            // A band a third of the marker wide, through its centre.
            let (s, c) = angle.sin_cos();
            let across = (p.x_mm - marker.x_mm) * -s + (p.y_mm - marker.y_mm) * c;
            if across.abs() <= marker_r / 3.0 && p.distance(marker) <= marker_r * 1.6 {
                return Some(CABLE);
            }
        }
        Some(if p.distance(marker) <= marker_r {
            MARKER
        } else {
            BODY
        })
    };
    // The patch: every pose's body, and the blur's reach around it twice
    // (the outer ring only feeds the inner one's blur).
    let reach = if optics.blur_px > 0.0 {
        (3.0 * optics.blur_px).ceil() as u32
    } else {
        0
    };
    let (w, h) = image.dimensions();
    let boxes = poses.iter().map(|pose| disc_bounds(pose.point(), r));
    let body = boxes
        .reduce(|(lo, hi), (l, h)| {
            let (x0, y0) = (lo.x_mm.min(l.x_mm), lo.y_mm.min(l.y_mm));
            let (x1, y1) = (hi.x_mm.max(h.x_mm), hi.y_mm.max(h.y_mm));
            (Point { x_mm: x0, y_mm: y0 }, Point { x_mm: x1, y_mm: y1 })
        })
        .expect("at least the pose now");
    let (cols, rows) = pixel_box(camera, optics, body);
    // The blur's reach twice, and a pixel for rounding.
    let grow = 1 + 2 * reach;
    let (c0, r0) = (
        cols.start.saturating_sub(grow),
        rows.start.saturating_sub(grow),
    );
    let (c1, r1) = ((cols.end + grow).min(w), (rows.end + grow).min(h));
    if c0 >= c1 || r0 >= r1 {
        return;
    }
    let mut patch = RgbImage::new(c1 - c0, r1 - r0);
    for (pc, pr, px) in patch.enumerate_pixels_mut() {
        let (c, rr) = (c0 + pc, r0 + pr);
        let still = *sharp.get_pixel(c, rr);
        let p = sample(camera, optics, c, rr);
        let mut sum = [0u32; 3];
        for pose in &poses {
            let seen = colour_at(pose, p).unwrap_or(still);
            for (total, channel) in sum.iter_mut().zip(seen.0) {
                *total += u32::from(channel);
            }
        }
        let n = poses.len() as u32;
        *px = Rgb(sum.map(|v| ((v + n / 2) / n) as u8));
    }
    if optics.blur_px > 0.0 {
        blur(&mut patch, optics.blur_px);
    }
    light(&mut patch, optics, (c0, r0), (w, h));
    // Only the inner part: its blur saw all its neighbours.
    let (pw, ph) = patch.dimensions();
    for pr in reach..ph.saturating_sub(reach) {
        for pc in reach..pw.saturating_sub(reach) {
            image.put_pixel(c0 + pc, r0 + pr, *patch.get_pixel(pc, pr));
        }
    }
}

/// What `camera` with `optics` shows of a calibration `target` laid on an
/// empty `width_mm` × `height_mm` floor.
pub fn render_target(
    target: &DotTarget,
    camera: &CameraModel,
    optics: &Optics,
    width_mm: f64,
    height_mm: f64,
) -> RgbImage {
    let camera = &optics.view(camera, width_mm, height_mm);
    let mut image = floor_and_walls(camera, optics, width_mm, height_mm, Rgb([30, 30, 30]));
    let dot = Rgb([20, 20, 24]);
    for centre in target.points() {
        let r = target.radius_mm;
        let bounds = disc_bounds(centre, r);
        paint(&mut image, camera, optics, bounds, |p| {
            (p.distance(centre) <= r).then_some(dot)
        });
    }
    finish(&mut image, optics, 0.0);
    image
}

/// A simulated camera calibrated as lab staff calibrate a real one, and
/// how far the result is from the truth the simulator knows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimCalibration {
    pub calibration: Calibration,
    /// The largest distance, over a grid across the floor, between where
    /// the calibrated model and the true camera put a floor point, px.
    pub truth_max_px: f64,
}

/// Lays `DotTarget::spread_over` the floor, takes its picture through
/// `optics`, and fits the camera from it.
pub fn calibrate(
    nominal: &CameraModel,
    optics: &Optics,
    width_mm: f64,
    height_mm: f64,
) -> Result<SimCalibration, CalibrationError> {
    let target = DotTarget::spread_over(width_mm, height_mm);
    let image = render_target(&target, nominal, optics, width_mm, height_mm);
    let calibration = target.calibrate(&image, nominal.fps)?;
    let truth = optics.view(nominal, width_mm, height_mm);
    let [dx, dy] = optics.lens_offset_px;
    let mut truth_max_px = 0.0f64;
    for i in 0..=16 {
        for j in 0..=12 {
            let p = Point {
                x_mm: f64::from(i) * width_mm / 16.0,
                y_mm: f64::from(j) * height_mm / 12.0,
            };
            let (c, r) = calibration.camera.to_pixel(p);
            let (c0, r0) = truth.to_pixel(p);
            truth_max_px = truth_max_px.max((c - c0 - dx).hypot(r - r0 - dy));
        }
    }
    Ok(SimCalibration {
        calibration,
        truth_max_px,
    })
}

/// The box around a disc of radius `r` at `centre`: what painting it covers.
fn disc_bounds(centre: Point, r: f64) -> (Point, Point) {
    Shape::Circle {
        x_mm: centre.x_mm,
        y_mm: centre.y_mm,
        radius_mm: r,
    }
    .bounds()
}

/// The floor point pixel (c, r)'s centre sees, through the lens offset.
fn sample(camera: &CameraModel, optics: &Optics, c: u32, r: u32) -> Point {
    let [dx, dy] = optics.lens_offset_px;
    camera.to_arena(f64::from(c) + 0.5 - dx, f64::from(r) + 0.5 - dy)
}

/// An image of the bare floor, with the walls' colour wherever a pixel
/// sees beyond it.
fn floor_and_walls(
    camera: &CameraModel,
    optics: &Optics,
    width_mm: f64,
    height_mm: f64,
    walls: Rgb<u8>,
) -> RgbImage {
    RgbImage::from_fn(camera.width_px, camera.height_px, |c, r| {
        let p = sample(camera, optics, c, r);
        if (0.0..=width_mm).contains(&p.x_mm) && (0.0..=height_mm).contains(&p.y_mm) {
            FLOOR
        } else {
            walls
        }
    })
}

/// The columns and rows of the pixels that see the floor box `(lo, hi)`
/// (mm), within the image.
fn pixel_box(
    camera: &CameraModel,
    optics: &Optics,
    (lo, hi): (Point, Point),
) -> (std::ops::Range<u32>, std::ops::Range<u32>) {
    let (w, h) = (camera.width_px, camera.height_px);
    let [dx, dy] = optics.lens_offset_px;
    // A homography takes the box to a quadrilateral inside its corners'
    // box; a lens bends its edges, so points along them count too.
    let along = if camera.distortion().is_none() { 1 } else { 8 };
    let corners: Vec<(f64, f64)> = (0..=along)
        .flat_map(|i| {
            let t = f64::from(i) / f64::from(along);
            let x = lo.x_mm + t * (hi.x_mm - lo.x_mm);
            let y = lo.y_mm + t * (hi.y_mm - lo.y_mm);
            [(x, lo.y_mm), (x, hi.y_mm), (lo.x_mm, y), (hi.x_mm, y)]
        })
        .map(|(x_mm, y_mm)| camera.to_pixel(Point { x_mm, y_mm }))
        .collect();
    let extent = |f: fn(f64, f64) -> f64, start: f64, pick: fn(&(f64, f64)) -> f64| {
        corners.iter().map(pick).fold(start, f)
    };
    let clamp = |v: f64, max: u32| {
        if v.is_nan() {
            0
        } else {
            v.floor().clamp(0.0, f64::from(max)) as u32
        }
    };
    let cols = clamp(extent(f64::min, f64::INFINITY, |p| p.0) + dx, w)
        ..clamp(extent(f64::max, f64::NEG_INFINITY, |p| p.0) + dx + 1.0, w);
    let rows = clamp(extent(f64::min, f64::INFINITY, |p| p.1) + dy, h)
        ..clamp(extent(f64::max, f64::NEG_INFINITY, |p| p.1) + dy + 1.0, h);
    (cols, rows)
}

/// Paints the pixels that see a floor point within `bounds` (mm) that
/// `colour` gives a colour.
fn paint(
    image: &mut RgbImage,
    camera: &CameraModel,
    optics: &Optics,
    (lo, hi): (Point, Point),
    colour: impl Fn(Point) -> Option<Rgb<u8>>,
) {
    let (cols, rows) = pixel_box(camera, optics, (lo, hi));
    for r in rows {
        for c in cols.clone() {
            if let Some(colour) = colour(sample(camera, optics, c, r)) {
                image.put_pixel(c, r, colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::Distortion;
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

    /// A dot target seen through a tilted, offset, blurred, noisy camera
    /// under a lamp calibrates the camera to within half a pixel
    /// everywhere on the floor.
    #[test]
    fn a_dot_target_calibrates_a_tilted_noisy_camera() {
        let nominal = CameraModel::overhead(800.0, 600.0, 640, 15.0);
        for (tilt, seed) in [(0.0, 1), (0.25, 2), (0.45, 3)] {
            let optics = Optics {
                tilt_rad: tilt,
                ..Optics::noisy(seed)
            };
            let fit = calibrate(&nominal, &optics, 800.0, 600.0).unwrap();
            println!(
                "tilt {tilt}: rms {:.3} px, {:.3} px from the truth at worst",
                fit.calibration.reprojection.rms_px, fit.truth_max_px
            );
            assert!(fit.calibration.reprojection.rms_px < 0.5, "{fit:?}");
            assert!(fit.truth_max_px < 0.5, "{fit:?}");
        }
    }

    /// Five targets seen through lenses of known distortion (the sensor's
    /// noise, blur and lamp, its lens centred: the model puts the
    /// distortion's centre at the image's): the lens is found within 10 %
    /// of each term, and the floor within half a pixel of where the true
    /// camera puts it.
    #[test]
    fn a_dot_target_measures_the_lens() {
        let nominal = CameraModel::overhead(800.0, 600.0, 640, 15.0);
        for (k1, k2, seed) in [
            (-0.12, 0.08, 1),
            (-0.18, 0.12, 2),
            (-0.25, 0.15, 3),
            (-0.3, 0.2, 4),
            (-0.22, 0.1, 5),
        ] {
            let optics = Optics {
                distortion: Distortion { k1, k2 },
                lens_offset_px: [0.0, 0.0],
                ..Optics::noisy(seed)
            };
            let fit = calibrate(&nominal, &optics, 800.0, 600.0).unwrap();
            let lens = fit.calibration.camera.distortion();
            println!(
                "k1 {k1} → {:.4}, k2 {k2} → {:.4}: rms {:.3} px, {:.3} px from the truth",
                lens.k1, lens.k2, fit.calibration.reprojection.rms_px, fit.truth_max_px
            );
            assert!(
                (lens.k1 - k1).abs() <= 0.1 * k1.abs(),
                "{lens:?} for {k1}, {k2}"
            );
            assert!(
                (lens.k2 - k2).abs() <= 0.1 * k2.abs(),
                "{lens:?} for {k1}, {k2}"
            );
            assert!(fit.truth_max_px < 0.5, "{fit:?}");
        }
    }

    /// A renderer that keeps the still scene between frames draws what a
    /// fresh one draws, frame after frame, and a box put down shows.
    #[test]
    fn the_kept_backdrop_is_what_a_fresh_render_draws() {
        let mut w = World::new(Arena::navigation(), RobotModel::khepera_ii(), 0).unwrap();
        w.schedule(crate::Scheduled {
            at_s: 0.3,
            event: crate::SceneEvent::Place("rect:600,100,40,40".parse().unwrap()),
        });
        let cam = camera_for(&w, 320, 15.0);
        for optics in [Optics::default(), Optics::noisy(3), Optics::realistic(4)] {
            let mut kept = Renderer::new(cam, optics);
            for _ in 0..6 {
                w.set_wheels(vl_core::WheelSpeeds {
                    left_mm_s: 150.0,
                    right_mm_s: 180.0,
                });
                w.run_for(0.1);
                assert!(
                    kept.render(&w) == w.render(&cam, &optics),
                    "{optics:?} at {}",
                    w.time_s()
                );
            }
        }
    }

    fn long_exposure() -> Optics {
        Optics {
            exposure_s: 0.1,
            ..Optics::default()
        }
    }

    /// A moving robot smears over a long exposure, a still one does not;
    /// a hidden marker shows less of itself.
    #[test]
    fn exposure_smears_and_a_cable_hides() {
        let mut w = World::new(Arena::navigation(), RobotModel::khepera_ii(), 0).unwrap();
        let cam = camera_for(&w, 640, 15.0);
        let marker = |image: &RgbImage| image.pixels().filter(|p| **p == MARKER).count();
        let at_rest = |w: &World| marker(&w.render(&cam, &long_exposure()));
        assert!(
            at_rest(&w) > 200,
            "a still robot is sharp whatever the exposure"
        );
        w.set_wheels(vl_core::WheelSpeeds {
            left_mm_s: 300.0,
            right_mm_s: 300.0,
        });
        w.run_for(0.5);
        let smeared = w.render(&cam, &long_exposure());
        let sharp = w.render(&cam, &Optics::default());
        assert!(
            marker(&smeared) < marker(&sharp) / 2,
            "{} vs {}",
            marker(&smeared),
            marker(&sharp)
        );
        let hidden = Optics {
            occlusion_rate: 0.5,
            ..Optics::default()
        };
        let mut partly = 0;
        for k in 0..20 {
            w.run_for(0.07 + 0.001 * f64::from(k));
            let seen = marker(&w.render(&cam, &hidden));
            let whole = marker(&w.render(&cam, &Optics::default()));
            assert!(seen <= whole);
            partly += usize::from(seen < whole * 4 / 5);
        }
        assert!(
            (3..=17).contains(&partly),
            "{partly} of 20 frames hid the marker"
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
