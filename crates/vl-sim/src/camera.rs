//! The overhead camera: renders the arena and the robot, seen from above.

use image::{Rgb, RgbImage};
use vl_core::camera::CameraModel;

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
    /// The overhead camera's view of the arena and the robot now.
    pub fn render(&self, camera: &CameraModel) -> RgbImage {
        let arena = self.arena();
        let robot = self.robot();
        let pose = self.pose();
        let marker = pose.to_world(robot.radius_mm * 0.45, 0.0);
        let marker_r = robot.radius_mm * 0.35;
        RgbImage::from_fn(camera.width_px, camera.height_px, |c, r| {
            let p = camera.to_arena(f64::from(c) + 0.5, f64::from(r) + 0.5);
            if p.distance(marker) <= marker_r {
                MARKER
            } else if p.distance(pose.point()) <= robot.radius_mm {
                BODY
            } else if arena.clearance(p) <= 0.0 {
                OBSTACLE
            } else {
                FLOOR
            }
        })
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
