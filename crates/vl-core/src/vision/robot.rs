//! The robot as the overhead camera marks it: a round body with a light
//! disc ahead of its centre.

use serde::Serialize;

use super::components::Component;

/// The robot's pose seen from above, in image pixels: x right, y down as
/// the image is stored, θ counter-clockwise from +x as the arena sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct RobotPose {
    pub x: f64,
    pub y: f64,
    pub theta: f64,
}
/// Whether a component is the robot as the camera marks it: a round body
/// (filled, it covers π/4 of its bounding box) with one light disc inside,
/// ahead of its centre, of about an eighth of the body's area.
pub fn is_robot(c: &Component) -> bool {
    let filled = (c.area + c.hole_area) as f64;
    let [_, _, bw, bh] = c.bbox;
    let box_area = f64::from(bw) * f64::from(bh);
    let roundness = filled / box_area;
    let marker = c.hole_area as f64 / filled;
    let square = f64::from(bw.min(bh)) / f64::from(bw.max(bh));
    c.hole_centroid.is_some()
        && (0.70..0.85).contains(&roundness)
        && square > 0.85
        && (0.05..0.25).contains(&marker)
}

/// The robot's pose from its component: the filled body's centroid is its
/// centre, and the marker lies ahead of it.
pub fn robot_pose(c: &Component) -> Option<RobotPose> {
    let hole = c.hole_centroid?;
    let (a, b) = (c.area as f64, c.hole_area as f64);
    let x = (a * c.centroid.x + b * hole.x) / (a + b);
    let y = (a * c.centroid.y + b * hole.y) / (a + b);
    // Rows grow downwards; the arena's y grows upwards.
    Some(RobotPose {
        x,
        y,
        theta: (y - hole.y).atan2(hole.x - x),
    })
}
