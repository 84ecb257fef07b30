//! The overhead camera: renders the arena and the robot, seen from above.

use image::{Rgb, RgbImage};
use vl_core::camera::CameraModel;
use vl_core::robot::Point;

use crate::world::World;

const FLOOR: Rgb<u8> = Rgb([226, 224, 216]);
const OBSTACLE: Rgb<u8> = Rgb([48, 50, 58]);
const BODY: Rgb<u8> = Rgb([196, 42, 38]);
/// A light disc on the front half of the body shows the heading.
const MARKER: Rgb<u8> = Rgb([250, 250, 250]);

/// A camera that sees the whole arena at `width_px` columns.
pub fn camera_for(world: &World, width_px: u32, fps: f64) -> CameraModel {
    let arena = world.arena();
    let mm_per_px = arena.width_mm / f64::from(width_px);
    CameraModel {
        width_px,
        height_px: (arena.height_mm / mm_per_px).ceil() as u32,
        mm_per_px,
        fps,
    }
}

impl World {
    /// The overhead camera's view of the arena and the robot now. Each shape
    /// is painted over its own bounding box only, so a frame costs about one
    /// pass over the image whatever the arena holds.
    pub fn render(&self, camera: &CameraModel) -> RgbImage {
        let arena = self.arena();
        let robot = self.robot();
        let pose = self.pose();
        let mut image = RgbImage::from_pixel(camera.width_px, camera.height_px, FLOOR);
        // Pixels whose centre lies beyond the walls.
        let inside = |p: Point| {
            (0.0..=arena.width_mm).contains(&p.x_mm) && (0.0..=arena.height_mm).contains(&p.y_mm)
        };
        paint(
            &mut image,
            camera,
            (Point::default(), Point::default()),
            true,
            |p| (!inside(p)).then_some(OBSTACLE),
        );
        for obstacle in &arena.obstacles {
            paint(&mut image, camera, obstacle.bounds(), false, |p| {
                (obstacle.distance(p) <= 0.0).then_some(OBSTACLE)
            });
        }
        let marker = pose.to_world(robot.radius_mm * 0.45, 0.0);
        let marker_r = robot.radius_mm * 0.35;
        let r = robot.radius_mm;
        let body = (
            Point {
                x_mm: pose.x_mm - r,
                y_mm: pose.y_mm - r,
            },
            Point {
                x_mm: pose.x_mm + r,
                y_mm: pose.y_mm + r,
            },
        );
        paint(&mut image, camera, body, false, |p| {
            if p.distance(marker) <= marker_r {
                Some(MARKER)
            } else {
                (p.distance(pose.point()) <= r).then_some(BODY)
            }
        });
        image
    }
}

/// Paints the pixels (centres) of `bounds` — or of the whole image when
/// `everywhere` — that `colour` gives a colour.
fn paint(
    image: &mut RgbImage,
    camera: &CameraModel,
    bounds: (Point, Point),
    everywhere: bool,
    colour: impl Fn(Point) -> Option<Rgb<u8>>,
) {
    let (w, h) = (camera.width_px, camera.height_px);
    let (cols, rows) = if everywhere {
        (0..w, 0..h)
    } else {
        let (c0, r1) = camera.to_pixel(bounds.0);
        let (c1, r0) = camera.to_pixel(bounds.1);
        let clamp = |v: f64, max: u32| v.floor().clamp(0.0, f64::from(max)) as u32;
        (
            clamp(c0, w)..clamp(c1 + 1.0, w),
            clamp(r0, h)..clamp(r1 + 1.0, h),
        )
    };
    for r in rows {
        for c in cols.clone() {
            let p = camera.to_arena(f64::from(c) + 0.5, f64::from(r) + 0.5);
            if let Some(colour) = colour(p) {
                image.put_pixel(c, r, colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::arena::Arena;
    use vl_core::robot::RobotModel;

    #[test]
    fn the_robot_appears_where_it_is() {
        let w = World::new(Arena::navigation(), RobotModel::khepera_ii(), 0).unwrap();
        let cam = camera_for(&w, 320, 10.0);
        assert_eq!((cam.width_px, cam.height_px), (320, 240));
        let img = w.render(&cam);
        let (c, r) = cam.to_pixel(w.pose().point());
        // Just behind the centre is body; in front of it, the heading marker.
        assert_eq!(*img.get_pixel(c as u32 - 8, r as u32), BODY);
        assert_eq!(*img.get_pixel(c as u32 + 6, r as u32), MARKER);
        // The box at x = 250..310, y = 0..230 is dark.
        let (bc, br) = cam.to_pixel(vl_core::robot::Point {
            x_mm: 280.0,
            y_mm: 100.0,
        });
        assert_eq!(*img.get_pixel(bc as u32, br as u32), OBSTACLE);
    }
}
