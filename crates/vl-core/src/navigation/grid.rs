//! Occupancy grids: a map's cells, blocked or free, laid out as ROS map
//! files lay them out: cell (column c, row r) of an H-row grid has its
//! centre at ((c + ½)·S, (H − r − ½)·S) mm, so row 0 is the image's top and
//! y points up.

use image::GrayImage;
use thiserror::Error;

use crate::{Arena, Point, Shape};

/// Why a grid or C-space could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CSpaceError {
    #[error("the scale must be a positive number of mm, got {0}")]
    Scale(f64),
    #[error("the map is empty (0 × 0 cells)")]
    Empty,
    #[error("the robot's footprint: {0}")]
    Footprint(String),
    #[error("the number of θ slices must be between 1 and 360, got {0}")]
    Slices(u32),
    #[error(
        "the C-space would have {cells} cells, more than the {MAX_CELLS} this planner holds: use larger cells (--cell-mm) or fewer θ slices"
    )]
    TooLarge { cells: u64 },
}

/// The most cells (over all θ slices) a C-space may have: about 1.5 GB
/// of grids, NF1 values and queue.
pub(crate) const MAX_CELLS: u64 = 200_000_000;

/// A square-celled occupancy grid: `blocked` is row-major from the top row.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub width: u32,
    pub height: u32,
    /// Side of a cell, mm.
    pub cell_mm: f64,
    pub blocked: Vec<bool>,
}

impl Grid {
    /// A grid of `width` × `height` free cells.
    pub fn free(width: u32, height: u32, cell_mm: f64) -> Result<Grid, CSpaceError> {
        if !(cell_mm.is_finite() && cell_mm > 0.0) {
            return Err(CSpaceError::Scale(cell_mm));
        }
        if width == 0 || height == 0 {
            return Err(CSpaceError::Empty);
        }
        let cells = u64::from(width) * u64::from(height);
        if cells > MAX_CELLS {
            return Err(CSpaceError::TooLarge { cells });
        }
        Ok(Grid {
            width,
            height,
            cell_mm,
            blocked: vec![false; width as usize * height as usize],
        })
    }

    /// The pixels of a top view darker than `threshold` are obstacles. The
    /// image is `mm_per_px` per pixel; cells are `cell_mm` (the pixels
    /// themselves when equal), and a cell is blocked when any pixel it
    /// overlaps is dark, so coarser cells never hide an obstacle.
    pub fn from_image(
        image: &GrayImage,
        threshold: u8,
        mm_per_px: f64,
        cell_mm: f64,
    ) -> Result<Grid, CSpaceError> {
        if !(mm_per_px.is_finite() && mm_per_px > 0.0) {
            return Err(CSpaceError::Scale(mm_per_px));
        }
        let (w, h) = image.dimensions();
        let cells = |px: u32| (f64::from(px) * mm_per_px / cell_mm - 1e-9).ceil().max(0.0) as u32;
        let mut grid = Grid::free(cells(w), cells(h), cell_mm)?;
        // Pixel spans covered by a cell, counted from the bottom (y up) so the
        // last partial cell is at the top, as in a ROS map with its origin
        // at the bottom-left.
        let ratio = cell_mm / mm_per_px;
        for r in 0..grid.height {
            let from_bottom = grid.height - 1 - r;
            let y0 = (f64::from(from_bottom) * ratio + 1e-9).floor() as u32;
            let y1 = ((f64::from(from_bottom + 1) * ratio - 1e-9).ceil() as u32).min(h);
            for c in 0..grid.width {
                let x0 = (f64::from(c) * ratio + 1e-9).floor() as u32;
                let x1 = ((f64::from(c + 1) * ratio - 1e-9).ceil() as u32).min(w);
                let dark = (y0..y1).any(|y| {
                    let row = h - 1 - y;
                    (x0..x1).any(|x| image.get_pixel(x, row).0[0] < threshold)
                });
                if dark {
                    let i = grid.index(c, r);
                    grid.blocked[i] = true;
                }
            }
        }
        Ok(grid)
    }

    /// The arena's floor in cells of `cell_mm`, its obstacles blocked.
    pub fn from_arena(arena: &Arena, cell_mm: f64) -> Result<Grid, CSpaceError> {
        if !(cell_mm.is_finite() && cell_mm > 0.0) {
            return Err(CSpaceError::Scale(cell_mm));
        }
        let cells = |mm: f64| (mm / cell_mm - 1e-9).ceil().max(0.0) as u32;
        let mut grid = Grid::free(cells(arena.width_mm), cells(arena.height_mm), cell_mm)?;
        for obstacle in &arena.obstacles {
            grid.block(&obstacle.shape);
        }
        Ok(grid)
    }

    pub fn index(&self, c: u32, r: u32) -> usize {
        r as usize * self.width as usize + c as usize
    }

    pub fn is_blocked(&self, c: u32, r: u32) -> bool {
        self.blocked[self.index(c, r)]
    }

    /// Width and height of the mapped floor, mm.
    pub fn size_mm(&self) -> (f64, f64) {
        (
            f64::from(self.width) * self.cell_mm,
            f64::from(self.height) * self.cell_mm,
        )
    }

    /// Where a cell's centre is, mm.
    pub fn centre(&self, c: u32, r: u32) -> Point {
        Point {
            x_mm: (f64::from(c) + 0.5) * self.cell_mm,
            y_mm: (f64::from(self.height - r) - 0.5) * self.cell_mm,
        }
    }

    /// The cell holding `p`, if it is on the map.
    pub fn cell_of(&self, p: Point) -> Option<(u32, u32)> {
        let c = (p.x_mm / self.cell_mm).floor();
        let from_bottom = (p.y_mm / self.cell_mm).floor();
        let inside = c >= 0.0
            && from_bottom >= 0.0
            && c < f64::from(self.width)
            && from_bottom < f64::from(self.height);
        inside.then(|| (c as u32, self.height - 1 - from_bottom as u32))
    }

    /// Blocks every cell whose centre lies in `shape` (a virtual obstacle,
    /// or an arena obstacle being mapped).
    pub fn block(&mut self, shape: &Shape) {
        let (lo, hi) = shape.bounds();
        let (Some(first), Some(last)) = (
            self.clamped_cell(Point {
                x_mm: lo.x_mm,
                y_mm: hi.y_mm,
            }),
            self.clamped_cell(Point {
                x_mm: hi.x_mm,
                y_mm: lo.y_mm,
            }),
        ) else {
            return;
        };
        for r in first.1..=last.1 {
            for c in first.0..=last.0 {
                if shape.distance(self.centre(c, r)) <= 0.0 {
                    let i = self.index(c, r);
                    self.blocked[i] = true;
                }
            }
        }
    }

    /// The cell nearest `p`, or None when `p` is so far off the map that
    /// nothing between it and the map could matter (a shape wholly outside).
    fn clamped_cell(&self, p: Point) -> Option<(u32, u32)> {
        let (w, h) = self.size_mm();
        if !(p.x_mm.is_finite() && p.y_mm.is_finite()) {
            return None;
        }
        let clamp = |v: f64, hi: f64| v.clamp(0.0, hi - self.cell_mm * 0.5);
        self.cell_of(Point {
            x_mm: clamp(p.x_mm, w),
            y_mm: clamp(p.y_mm, h),
        })
    }

    /// Distance, in cells, from a cell's centre to the centre of the
    /// nearest cell just off the map.
    pub fn border_cells(&self, c: u32, r: u32) -> f64 {
        f64::from((c + 1).min(self.width - c).min(r + 1).min(self.height - r))
    }
}
