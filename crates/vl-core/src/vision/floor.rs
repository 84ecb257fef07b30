//! What a frame of the overhead camera says about the floor: where the
//! robot is, and which of the floor's cells something else covers. The
//! camera is the lab's sensor (thesis B.1, B.3): the Host builds the map
//! it plans and guards on from these cells, and localises the robot in
//! every frame.

use image::{GrayImage, Luma, RgbImage};

use super::{Connectivity, Mask, binarise, components, grey, is_robot, otsu, robot_pose};
use crate::model::arena::map::dark_boxes;
use crate::model::camera::CameraModel;
use crate::navigation::grid::{CSpaceError, Grid};
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

/// How far around the robot's blob `erase_robot` paints, px: blur and
/// antialiasing leave a rim that would still show a ghost of the body.
const ERASE_RIM_PX: i64 = 3;

impl Look {
    /// Paints the robot out of `frame` (the frame this look was taken
    /// of) with the floor's colour around it, so a frame kept on screen
    /// while the robot moves on shows no stale robot: the viewer draws it
    /// from its pose.
    pub fn erase_robot(&self, frame: &mut RgbImage) {
        let Some(label) = self.robot_label else {
            return;
        };
        let (w, h) = (i64::from(self.mask.width), i64::from(self.mask.height));
        let mut lo = (w, h);
        let mut hi = (-1, -1);
        for (i, &l) in self.labels.iter().enumerate() {
            if l == label {
                let (c, r) = (i as i64 % w, i as i64 / w);
                lo = (lo.0.min(c), lo.1.min(r));
                hi = (hi.0.max(c), hi.1.max(r));
            }
        }
        if hi.0 < 0 {
            return;
        }
        let rim = ERASE_RIM_PX;
        let (c0, r0) = ((lo.0 - rim).max(0), (lo.1 - rim).max(0));
        let (c1, r1) = ((hi.0 + rim).min(w - 1), (hi.1 + rim).min(h - 1));
        let is_robot = |c: i64, r: i64| self.labels[(r * w + c) as usize] == label;
        let near_robot = |c: i64, r: i64| {
            (r - rim..=r + rim).any(|rr| {
                (c - rim..=c + rim)
                    .any(|cc| (0..w).contains(&cc) && (0..h).contains(&rr) && is_robot(cc, rr))
            })
        };
        // The floor's colour: the mean of the light pixels on the box's edge.
        let mut sum = [0u64; 3];
        let mut n = 0u64;
        for r in r0..=r1 {
            for c in c0..=c1 {
                let edge = r == r0 || r == r1 || c == c0 || c == c1;
                if edge && !self.mask.pixels[(r * w + c) as usize] && !near_robot(c, r) {
                    let p = frame.get_pixel(c as u32, r as u32).0;
                    for k in 0..3 {
                        sum[k] += u64::from(p[k]);
                    }
                    n += 1;
                }
            }
        }
        if n == 0 {
            return;
        }
        let floor = image::Rgb(sum.map(|v| (v / n) as u8));
        for r in r0..=r1 {
            // The body's span on this row, its light marker (a hole in
            // the body's component) included.
            let row = |c: &i64| (0..h).contains(&r) && is_robot(*c, r);
            let span = (c0..=c1).find(row).zip((c0..=c1).rev().find(row));
            for c in c0..=c1 {
                let inside = span.is_some_and(|(a, b)| (a..=b).contains(&c));
                if inside || near_robot(c, r) {
                    frame.put_pixel(c as u32, r as u32, floor);
                }
            }
        }
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
