//! The overhead camera's model: how arena millimetres map to image pixels.
//!
//! The frame follows ROS map files: the image's bottom-left corner is the
//! arena origin, x right, y up, so pixel (column c, row r) of an H-row
//! image has its centre at ((c + 0.5)·S, (H − r − 0.5)·S) for S mm per pixel.

use serde::{Deserialize, Serialize};

use crate::Point;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    pub width_px: u32,
    pub height_px: u32,
    pub mm_per_px: f64,
    /// Frames per second the Host captures at.
    pub fps: f64,
}

impl CameraModel {
    /// A camera looking straight down at a `width_mm` × `height_mm` floor,
    /// seeing all of it across `width_px` columns.
    pub fn overhead(width_mm: f64, height_mm: f64, width_px: u32, fps: f64) -> CameraModel {
        let mm_per_px = width_mm / f64::from(width_px);
        CameraModel {
            width_px,
            height_px: (height_mm / mm_per_px).ceil() as u32,
            mm_per_px,
            fps,
        }
    }

    /// Continuous image coordinates (column, row) of an arena point: pixel
    /// (c, r) covers [c, c+1) × [r, r+1).
    pub fn to_pixel(&self, p: Point) -> (f64, f64) {
        (
            p.x_mm / self.mm_per_px,
            f64::from(self.height_px) - p.y_mm / self.mm_per_px,
        )
    }

    /// The arena point at continuous image coordinates (column, row).
    pub fn to_arena(&self, col: f64, row: f64) -> Point {
        Point {
            x_mm: col * self.mm_per_px,
            y_mm: (f64::from(self.height_px) - row) * self.mm_per_px,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_centres_follow_the_ros_convention() {
        let cam = CameraModel {
            width_px: 320,
            height_px: 240,
            mm_per_px: 2.5,
            fps: 10.0,
        };
        let centre = cam.to_arena(0.5, 239.5);
        assert_eq!(
            centre,
            Point {
                x_mm: 1.25,
                y_mm: 1.25
            }
        );
        assert_eq!(cam.to_pixel(centre), (0.5, 239.5));
    }
}
