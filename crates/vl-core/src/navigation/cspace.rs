//! Configuration space for a robot moving in the plane with heading θ: the
//! map's obstacles (dark pixels of a top view, plus virtual shapes) grown by
//! the robot's footprint, one occupancy grid per θ slice.
//!
//! Grids follow ROS map files: cell (column c, row r) of an H-row grid has
//! its centre at ((c + ½)·S, (H − r − ½)·S) mm, so row 0 is the image's top
//! and y points up. Everything outside the grid counts as an obstacle: an
//! arena image ends at the arena's walls.

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

/// The robot's outline as the planner sees it, in its own frame (x forward,
/// y left, mm, origin at the point that follows the path).
#[derive(Debug, Clone, PartialEq)]
pub enum Footprint {
    Disc { radius_mm: f64 },
    Polygon { points: Vec<Point> },
}

impl Footprint {
    fn check(&self) -> Result<(), CSpaceError> {
        let bad = |why: String| Err(CSpaceError::Footprint(why));
        match self {
            Footprint::Disc { radius_mm } if !(radius_mm.is_finite() && *radius_mm >= 0.0) => {
                bad(format!("the radius must be 0 or more mm, got {radius_mm}"))
            }
            Footprint::Disc { .. } => Ok(()),
            Footprint::Polygon { points } => Shape::Polygon {
                points: points.clone(),
            }
            .check()
            .or_else(|e| bad(e.to_string())),
        }
    }

    /// The largest distance from the reference point to the outline: how far
    /// a turn in place can sweep.
    pub fn reach_mm(&self) -> f64 {
        match self {
            Footprint::Disc { radius_mm } => *radius_mm,
            Footprint::Polygon { points } => points
                .iter()
                .map(|p| p.x_mm.hypot(p.y_mm))
                .fold(0.0, f64::max),
        }
    }
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

    /// Squared distance, in cells², from each cell's centre to the nearest
    /// blocked cell's centre: the exact Euclidean distance transform of
    /// Felzenszwalb and Huttenlocher. [`FAR`] where there is none (within
    /// 65,534 rows: the first pass counts in 16 bits). See
    /// [`Self::distance_transform_within`].
    pub fn distance_transform(&self) -> Vec<u32> {
        self.distance_transform_within(FAR - 1)
    }

    /// The distance transform, exact wherever it is at most `limit` cells²
    /// and [`FAR`] wherever it is more: a C-space only asks "nearer than
    /// this?", and a cell farther from every obstacle than the limit along
    /// its column cannot be anyone's nearest, so the second pass skips it.
    fn distance_transform_within(&self, limit: u32) -> Vec<u32> {
        let mut d = vec![FAR; self.blocked.len()];
        self.transform_rows(limit, &mut d, |row, out| out.copy_from_slice(row));
        d
    }

    /// The cells whose centres are within `limit` cells² of a blocked cell's
    /// centre (the blocked ones among them), without holding the whole
    /// transform.
    fn within(&self, limit: u32) -> Vec<bool> {
        let mut near = vec![false; self.blocked.len()];
        self.transform_rows(limit, &mut near, |row, out| {
            for (o, &d) in out.iter_mut().zip(row) {
                *o = d != FAR;
            }
        });
        near
    }

    /// Takes the transform within `limit` row by row, handing `write` each
    /// row's squared distances with that row of `out`.
    ///
    /// The first pass (along columns) is, for a binary map, the distance to
    /// the nearest blocked cell in the column, taken by two sweeps over whole
    /// rows so memory is read in order, and held in 16 bits; the second (the
    /// lower envelope of parabolas along each row, or a sliding minimum for
    /// a small limit) splits its rows between two threads on a large map.
    /// Cells off the map are not counted here; see [`Grid::border_cells`].
    fn transform_rows<T: Send>(
        &self,
        limit: u32,
        out: &mut [T],
        write: impl Fn(&[u32], &mut [T]) + Sync,
    ) {
        let (w, h) = (self.width as usize, self.height as usize);
        // Rows to the nearest blocked cell up or down the column, saturating
        // at NONE: "none within reach". Written without branches (a mask for
        // "blocked") so the sweeps vectorise.
        const NONE: u16 = u16::MAX;
        let mut column = vec![NONE; w * h];
        let free = |b: bool| u16::from(b).wrapping_sub(1);
        for (g, &b) in column.iter_mut().zip(&self.blocked).take(w) {
            *g = NONE & free(b);
        }
        for y in 1..h {
            let (done, row) = column.split_at_mut(y * w);
            let above = &done[(y - 1) * w..];
            let blocked = &self.blocked[y * w..(y + 1) * w];
            for ((g, &a), &b) in row[..w].iter_mut().zip(above).zip(blocked) {
                *g = a.saturating_add(1) & free(b);
            }
        }
        for y in (0..h.saturating_sub(1)).rev() {
            let (row, below) = column[y * w..(y + 2) * w].split_at_mut(w);
            for (g, &b) in row.iter_mut().zip(below.iter()) {
                *g = (*g).min(b.saturating_add(1));
            }
        }
        let reach = limit.isqrt();
        let rows = |column: &[u16], out: &mut [T]| {
            let mut scratch = Scratch::new(w);
            let mut row = vec![0u32; w];
            for (g, out) in column.chunks_exact(w).zip(out.chunks_exact_mut(w)) {
                for (r, &g) in row.iter_mut().zip(g) {
                    *r = if g == NONE { NONE_U32 } else { u32::from(g) };
                }
                if reach <= WINDOW_REACH {
                    scratch.window(&mut row, limit);
                } else {
                    scratch.lower_envelope(&mut row, limit);
                }
                write(&row, out);
            }
        };
        if w * h >= PARALLEL_CELLS && h >= 2 {
            let half = h / 2 * w;
            let (top, bottom) = column.split_at(half);
            let (out_top, out_bottom) = out.split_at_mut(half);
            std::thread::scope(|scope| {
                scope.spawn(|| rows(top, out_top));
                rows(bottom, out_bottom);
            });
        } else {
            rows(&column, out);
        }
    }

    /// Distance, in cells, from a cell's centre to the centre of the
    /// nearest cell just off the map.
    pub fn border_cells(&self, c: u32, r: u32) -> f64 {
        f64::from((c + 1).min(self.width - c).min(r + 1).min(self.height - r))
    }
}

/// The distance transform's value for "no blocked cell within the limit".
pub const FAR: u32 = u32::MAX;

/// A row's column distance where the column has no blocked cell within reach.
const NONE_U32: u32 = u32::MAX;

/// Maps at least this large share the distance transform's rows between two
/// threads: below it, starting a thread costs more than it saves.
const PARALLEL_CELLS: usize = 1 << 16;

/// Limits up to this many cells out are taken along a row by a sliding
/// minimum over the window, cheaper there than the lower envelope.
const WINDOW_REACH: u32 = 8;

/// Buffers for the 1-D squared distance transform along a row.
struct Scratch {
    /// Columns of the parabolas that may be nearest (within the limit).
    at: Vec<usize>,
    /// Their heights: the squared column distance there.
    f: Vec<f64>,
    /// Columns of the parabolas in the lower envelope.
    v: Vec<usize>,
    /// Where each envelope parabola starts to be the lowest.
    z: Vec<f64>,
    /// The window's squared column distances, capped just past the limit.
    g2: Vec<u32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            at: Vec::with_capacity(n),
            f: Vec::with_capacity(n),
            v: vec![0; n],
            z: vec![0.0; n + 1],
            g2: vec![0; n],
        }
    }

    /// Replaces `row`'s column distances ([`NONE_U32`] for "no blocked
    /// cell within reach") by squared distances within `limit` and [`FAR`] beyond it:
    /// the lower envelope of parabolas of Felzenszwalb and Huttenlocher,
    /// over only the columns near enough to count.
    fn lower_envelope(&mut self, row: &mut [u32], limit: u32) {
        self.at.clear();
        self.f.clear();
        for (x, &g) in row.iter().enumerate() {
            if g != NONE_U32 && u64::from(g) * u64::from(g) <= u64::from(limit) {
                self.at.push(x);
                self.f.push(f64::from(g) * f64::from(g));
            }
        }
        if self.at.is_empty() {
            row.fill(FAR);
            return;
        }
        let (at, f, v, z) = (&self.at, &self.f, &mut self.v, &mut self.z);
        let mut k = 0usize;
        v[0] = 0;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        let sq = |i: usize| (at[i] * at[i]) as f64;
        for q in 1..at.len() {
            loop {
                let p = v[k];
                let s = ((f[q] + sq(q)) - (f[p] + sq(p))) / (2.0 * (at[q] - at[p]) as f64);
                if s <= z[k] && k > 0 {
                    k -= 1;
                } else {
                    k += 1;
                    v[k] = q;
                    z[k] = s;
                    z[k + 1] = f64::INFINITY;
                    break;
                }
            }
        }
        k = 0;
        let limit = f64::from(limit);
        for (x, out) in row.iter_mut().enumerate() {
            while z[k + 1] < x as f64 {
                k += 1;
            }
            let dx = x as f64 - at[v[k]] as f64;
            let d2 = dx * dx + f[v[k]];
            *out = if d2 <= limit { d2 as u32 } else { FAR };
        }
    }

    /// The same as [`Self::lower_envelope`] for a small `limit`: each cell
    /// takes the least dx² + g² over the columns within its square root.
    fn window(&mut self, row: &mut [u32], limit: u32) {
        let reach = limit.isqrt() as usize;
        let beyond = limit + 1;
        let g2 = &mut self.g2[..row.len()];
        for (h, &g) in g2.iter_mut().zip(row.iter()) {
            *h = if (g as usize) <= reach { g * g } else { beyond };
        }
        row.copy_from_slice(g2);
        for dx in 1..reach.min(row.len().saturating_sub(1)) + 1 {
            let d = (dx * dx) as u32;
            let n = row.len() - dx;
            for (out, &h) in row[..n].iter_mut().zip(&g2[dx..]) {
                *out = (*out).min(h + d);
            }
            for (out, &h) in row[dx..].iter_mut().zip(&g2[..n]) {
                *out = (*out).min(h + d);
            }
        }
        for out in row.iter_mut() {
            if *out > limit {
                *out = FAR;
            }
        }
    }
}

/// The configuration space: for each θ slice, the cells where the robot's
/// reference point may stand without its footprint covering an obstacle
/// cell's centre or leaving the map. A disc looks the same at every θ, so it
/// has one slice.
#[derive(Debug, Clone, PartialEq)]
pub struct CSpace {
    pub slices: Vec<Grid>,
    pub footprint: Footprint,
}

impl CSpace {
    /// Grows the obstacles of `workspace` by `footprint`, with
    /// `theta_slices` headings for a polygon (slice k is θ = 2πk/n).
    pub fn build(
        workspace: &Grid,
        footprint: Footprint,
        theta_slices: u32,
    ) -> Result<CSpace, CSpaceError> {
        footprint.check()?;
        if !(1..=360).contains(&theta_slices) {
            return Err(CSpaceError::Slices(theta_slices));
        }
        let slices = if matches!(footprint, Footprint::Disc { .. }) {
            1
        } else {
            theta_slices
        };
        let cells = workspace.blocked.len() as u64 * u64::from(slices);
        if cells > MAX_CELLS {
            return Err(CSpaceError::TooLarge { cells });
        }
        let slices = match &footprint {
            Footprint::Disc { radius_mm } => vec![grow_by_disc(workspace, *radius_mm)],
            Footprint::Polygon { points } => (0..theta_slices)
                .map(|k| {
                    let theta = std::f64::consts::TAU * f64::from(k) / f64::from(theta_slices);
                    grow_by_stamp(workspace, &stamp(points, theta, workspace.cell_mm))
                })
                .collect(),
        };
        Ok(CSpace { slices, footprint })
    }

    /// The slice nearest heading `theta_rad`.
    pub fn slice_of(&self, theta_rad: f64) -> usize {
        if self.slices.len() == 1 {
            return 0;
        }
        let n = self.slices.len() as f64;
        let k = (theta_rad.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU * n).round();
        (k as usize) % self.slices.len()
    }

    /// The heading slice `k` stands for.
    pub fn theta_of(&self, k: usize) -> f64 {
        std::f64::consts::TAU * k as f64 / self.slices.len() as f64
    }

    pub fn grid(&self) -> &Grid {
        &self.slices[0]
    }

    /// Whether the robot may stand at `p` with heading `theta_rad`.
    pub fn is_free(&self, p: Point, theta_rad: f64) -> bool {
        let grid = &self.slices[self.slice_of(theta_rad)];
        grid.cell_of(p).is_some_and(|(c, r)| !grid.is_blocked(c, r))
    }
}

/// Blocks the cells within `radius_mm` (centre to centre) of an obstacle
/// cell or of the map's edge.
fn grow_by_disc(workspace: &Grid, radius_mm: f64) -> Grid {
    if radius_mm <= 0.0 {
        return workspace.clone();
    }
    let r_cells = radius_mm / workspace.cell_mm;
    let r2 = r_cells * r_cells + 1e-9;
    let mut grown = Grid {
        blocked: workspace.within(r2.min(f64::from(FAR - 1)) as u32),
        ..*workspace
    };
    // The bands along the edges, whose centres are within the radius of a
    // cell just off the map.
    let band = |n: u32| (0..n).filter(move |&i| f64::from((i + 1).min(n - i)) <= r_cells + 1e-9);
    for r in band(workspace.height) {
        for c in 0..workspace.width {
            grown.blocked[workspace.index(c, r)] = true;
        }
    }
    for c in band(workspace.width) {
        for r in 0..workspace.height {
            grown.blocked[workspace.index(c, r)] = true;
        }
    }
    grown
}

/// The cell offsets (dc, dr) whose centres the footprint covers when the
/// reference point stands on a cell centre with heading `theta`, as runs
/// `(dr, dc_first, dc_last)`.
fn stamp(points: &[Point], theta: f64, cell_mm: f64) -> Vec<(i64, i64, i64)> {
    let (s, c) = theta.sin_cos();
    let turned: Vec<Point> = points
        .iter()
        .map(|p| Point {
            x_mm: p.x_mm * c - p.y_mm * s,
            y_mm: p.x_mm * s + p.y_mm * c,
        })
        .collect();
    let polygon = Shape::Polygon { points: turned };
    let (lo, hi) = polygon.bounds();
    let cells = |v: f64| (v / cell_mm).round() as i64;
    let mut runs = Vec::new();
    for dy in cells(lo.y_mm) - 1..=cells(hi.y_mm) + 1 {
        let mut run: Option<(i64, i64)> = None;
        for dx in cells(lo.x_mm) - 1..=cells(hi.x_mm) + 1 {
            let p = Point {
                x_mm: dx as f64 * cell_mm,
                y_mm: dy as f64 * cell_mm,
            };
            if polygon.distance(p) <= 0.0 {
                run = Some(run.map_or((dx, dx), |(a, _)| (a, dx)));
            } else if let Some((a, b)) = run.take() {
                runs.push((-dy, a, b)); // rows count down, y up
            }
        }
        if let Some((a, b)) = run {
            runs.push((-dy, a, b));
        }
    }
    runs
}

/// Blocks each cell from which the stamp reaches an obstacle cell or off
/// the map, using per-row prefix counts so each run costs O(1).
fn grow_by_stamp(workspace: &Grid, runs: &[(i64, i64, i64)]) -> Grid {
    let (w, h) = (i64::from(workspace.width), i64::from(workspace.height));
    let stride = w as usize + 1;
    let mut prefix = vec![0u32; stride * h as usize];
    for r in 0..h as usize {
        for c in 0..w as usize {
            prefix[r * stride + c + 1] =
                prefix[r * stride + c] + u32::from(workspace.blocked[r * w as usize + c]);
        }
    }
    let mut grown = workspace.clone();
    for r in 0..h {
        for c in 0..w {
            let hits = runs.iter().any(|&(dr, a, b)| {
                let (row, c0, c1) = (r + dr, c + a, c + b);
                if row < 0 || row >= h || c0 < 0 || c1 >= w {
                    return true;
                }
                let base = row as usize * stride;
                prefix[base + c1 as usize + 1] > prefix[base + c0 as usize]
            });
            if hits {
                grown.blocked[(r * w + c) as usize] = true;
            }
        }
    }
    grown
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> Grid {
        let mut g = Grid::free(rows[0].len() as u32, rows.len() as u32, 10.0).unwrap();
        for (r, row) in rows.iter().enumerate() {
            for (c, ch) in row.chars().enumerate() {
                g.blocked[r * row.len() + c] = ch == '#';
            }
        }
        g
    }

    #[test]
    fn cell_centres_follow_the_ros_map_frame() {
        let g = grid(&["...", "..."]);
        assert_eq!(
            g.centre(0, 1),
            Point {
                x_mm: 5.0,
                y_mm: 5.0
            }
        );
        assert_eq!(
            g.cell_of(Point {
                x_mm: 25.0,
                y_mm: 19.0
            }),
            Some((2, 0))
        );
        assert_eq!(
            g.cell_of(Point {
                x_mm: 30.0,
                y_mm: 1.0
            }),
            None
        );
    }

    /// The squared distance from each cell to the nearest blocked one, by
    /// looking at every blocked cell (infinite without one).
    fn brute_force(g: &Grid) -> Vec<f64> {
        let mut d = vec![f64::INFINITY; (g.width * g.height) as usize];
        for r in 0..g.height {
            for c in 0..g.width {
                for (cc, rr) in (0..g.height)
                    .flat_map(|rr| (0..g.width).map(move |cc| (cc, rr)))
                    .filter(|&(cc, rr)| g.is_blocked(cc, rr))
                {
                    let (dc, dr) = (f64::from(cc) - f64::from(c), f64::from(rr) - f64::from(r));
                    let i = g.index(c, r);
                    d[i] = d[i].min(dc * dc + dr * dr);
                }
            }
        }
        d
    }

    #[test]
    fn distance_transform_matches_brute_force() {
        let g = grid(&["#.....", "......", "...#..", "......"]);
        let want: Vec<u32> = brute_force(&g).iter().map(|&d| d as u32).collect();
        assert_eq!(g.distance_transform(), want);
    }

    use proptest::prelude::*;

    proptest! {
        /// Exact on any grid: equal to the brute force wherever a blocked
        /// cell exists, and beyond every distance on the map where none does.
        #[test]
        fn distance_transform_is_exact(
            (w, h, cells) in (1u32..24, 1u32..24).prop_flat_map(|(w, h)| {
                (Just(w), Just(h), proptest::collection::vec(any::<u8>(), (w * h) as usize))
            })
        ) {
            let mut g = Grid::free(w, h, 10.0).unwrap();
            for (b, c) in g.blocked.iter_mut().zip(&cells) {
                *b = *c < 20;
            }
            let fast = g.distance_transform();
            for (got, want) in fast.iter().zip(brute_force(&g)) {
                if want.is_finite() {
                    prop_assert_eq!(f64::from(*got), want);
                } else {
                    prop_assert_eq!(*got, FAR);
                }
            }
        }

        /// Within a limit: exact up to it, FAR beyond it.
        #[test]
        fn distance_transform_within_a_limit_is_exact_up_to_it(
            (w, h, cells) in (1u32..24, 1u32..24).prop_flat_map(|(w, h)| {
                (Just(w), Just(h), proptest::collection::vec(any::<u8>(), (w * h) as usize))
            }),
            limit in 0u32..300,
        ) {
            let mut g = Grid::free(w, h, 10.0).unwrap();
            for (b, c) in g.blocked.iter_mut().zip(&cells) {
                *b = *c < 8;
            }
            let near = g.distance_transform_within(limit);
            for (got, want) in near.iter().zip(brute_force(&g)) {
                if want <= f64::from(limit) {
                    prop_assert_eq!(f64::from(*got), want);
                } else {
                    prop_assert_eq!(*got, FAR);
                }
            }
        }
    }

    #[test]
    fn a_disc_grows_obstacles_and_walls() {
        let g = grid(&[".......", ".......", "...#...", ".......", "......."]);
        let cs = CSpace::build(&g, Footprint::Disc { radius_mm: 10.0 }, 1).unwrap();
        let s = &cs.slices[0];
        assert!(s.is_blocked(3, 1) && s.is_blocked(2, 2) && !s.is_blocked(2, 1));
        assert!(s.is_blocked(0, 2), "one cell from the edge");
        assert!(!s.is_blocked(1, 3));
    }

    #[test]
    fn a_bar_blocks_differently_per_heading() {
        let g = grid(&[
            ".........",
            ".........",
            ".........",
            "....#....",
            ".........",
            ".........",
            ".........",
        ]);
        // A bar 50 mm long along the robot's x, 1 mm wide.
        let bar = Footprint::Polygon {
            points: vec![
                Point {
                    x_mm: -25.0,
                    y_mm: -0.5,
                },
                Point {
                    x_mm: 25.0,
                    y_mm: -0.5,
                },
                Point {
                    x_mm: 25.0,
                    y_mm: 0.5,
                },
                Point {
                    x_mm: -25.0,
                    y_mm: 0.5,
                },
            ],
        };
        let cs = CSpace::build(&g, bar, 4).unwrap();
        // Facing +x, the bar reaches the obstacle from two cells to its left …
        assert!(cs.slices[0].is_blocked(2, 3));
        assert!(!cs.slices[0].is_blocked(4, 1));
        // … facing +y, from two cells below it.
        assert!(cs.slices[1].is_blocked(4, 5));
        assert!(!cs.slices[1].is_blocked(2, 3));
        assert_eq!(cs.slice_of(std::f64::consts::FRAC_PI_2), 1);
    }

    #[test]
    fn coarser_cells_keep_every_dark_pixel() {
        let mut image = GrayImage::from_pixel(10, 10, image::Luma([255]));
        image.put_pixel(9, 0, image::Luma([0]));
        let g = Grid::from_image(&image, 128, 1.0, 4.0).unwrap();
        assert_eq!((g.width, g.height), (3, 3));
        // Pixel (9, 0) is 9–10 mm right and 9–10 mm up: the top-right cell.
        assert!(g.is_blocked(2, 0));
        assert_eq!(g.blocked.iter().filter(|&&b| b).count(), 1);
        assert_eq!(
            Grid::from_image(&image, 128, 0.0, 1.0),
            Err(CSpaceError::Scale(0.0))
        );
    }
}
