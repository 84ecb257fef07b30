//! What a frame of the overhead camera says about the floor: where the
//! robot is, and which of the floor's cells something else covers. The
//! camera is the lab's sensor (thesis B.1, B.3): the Host builds the map
//! it plans and guards on from these cells, and localises the robot in
//! every frame.

use image::{GrayImage, Luma, RgbImage};

use super::{Connectivity, Mask, binarise, components, grey, is_robot, otsu, robot_pose};
use crate::model::arena::map::dark_boxes;
use crate::model::camera::CameraModel;
use crate::navigation::cspace::{CSpaceError, Grid};
use crate::{Arena, Material, Obstacle, Point, Pose};

/// One frame, binarised and labelled: dark pixels are obstacles or the
/// robot's body.
#[derive(Debug, Clone)]
pub struct Look {
    mask: Mask,
    labels: Vec<u32>,
    robot_label: Option<u32>,
    /// The robot's pose on the floor, if the frame shows it.
    pub robot: Option<Pose>,
}

/// Binarises `frame` at Otsu's threshold (dark objects on a light floor),
/// labels it, and finds the robot by its marker.
pub fn look(frame: &RgbImage, camera: &CameraModel) -> Look {
    let grey = grey(frame);
    let mask = binarise(&grey, otsu(&grey), true);
    let (found, labels) = components(&mask, Connectivity::Eight);
    let robot = found.iter().find(|c| is_robot(c));
    let pose = robot.and_then(|c| {
        let body = robot_pose(c)?;
        let hole = c.hole_centroid?;
        // Pixel (c, r) covers [c, c+1) × [r, r+1): its centre is c + ½.
        let centre = camera.to_arena(body.x + 0.5, body.y + 0.5);
        let marker = camera.to_arena(hole.x + 0.5, hole.y + 0.5);
        Some(Pose {
            x_mm: centre.x_mm,
            y_mm: centre.y_mm,
            theta_rad: (marker.y_mm - centre.y_mm).atan2(marker.x_mm - centre.x_mm),
        })
    });
    Look {
        mask,
        labels,
        robot_label: robot.map(|c| c.label),
        robot: pose,
    }
}

impl Look {
    /// The `width_mm` × `height_mm` floor in cells of `cell_mm`, each
    /// blocked when the pixel at its centre is dark and not the robot's, or
    /// when the camera does not see it.
    pub fn obstacles(
        &self,
        camera: &CameraModel,
        width_mm: f64,
        height_mm: f64,
        cell_mm: f64,
    ) -> Result<Grid, CSpaceError> {
        let cells = |mm: f64| (mm / cell_mm - 1e-9).ceil().max(0.0) as u32;
        let mut grid = Grid::free(cells(width_mm), cells(height_mm), cell_mm)?;
        let (w, h) = (self.mask.width, self.mask.height);
        for r in 0..grid.height {
            for c in 0..grid.width {
                let (col, row) = camera.to_pixel(grid.centre(c, r));
                let seen = (0.0..f64::from(w)).contains(&col) && (0.0..f64::from(h)).contains(&row);
                let blocked = !seen || {
                    let i = row as usize * w as usize + col as usize;
                    self.mask.pixels[i] && Some(self.labels[i]) != self.robot_label
                };
                let i = grid.index(c, r);
                grid.blocked[i] = blocked;
            }
        }
        Ok(grid)
    }
}

/// The arena `grid` describes: its blocked cells as few rectangles, on a
/// floor of its size, the robot (if seen) at `start`.
pub fn arena_of(grid: &Grid, name: &str, start: Option<Pose>) -> Arena {
    let image = GrayImage::from_fn(grid.width, grid.height, |c, r| {
        Luma([if grid.is_blocked(c, r) { 0 } else { 255 }])
    });
    let (width_mm, height_mm) = grid.size_mm();
    Arena {
        name: name.to_owned(),
        width_mm,
        height_mm,
        obstacles: dark_boxes(&image, 128, grid.cell_mm)
            .into_iter()
            .map(|shape| Obstacle {
                shape,
                material: Material::default(),
            })
            .collect(),
        walls: Material::default(),
        start: start.unwrap_or(Pose {
            x_mm: width_mm / 2.0,
            y_mm: height_mm / 2.0,
            theta_rad: 0.0,
        }),
        goal: None::<Point>,
    }
}

/// Cells in which two grids of one floor differ.
pub fn changed_cells(a: &Grid, b: &Grid) -> usize {
    if (a.width, a.height) != (b.width, b.height) {
        return a.blocked.len().max(b.blocked.len());
    }
    a.blocked
        .iter()
        .zip(&b.blocked)
        .filter(|(x, y)| x != y)
        .count()
}
