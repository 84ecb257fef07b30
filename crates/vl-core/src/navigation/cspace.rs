//! Configuration space for a robot moving in the plane with heading θ: the
//! map's obstacles (dark pixels of a top view, plus virtual shapes) grown by
//! the robot's footprint, one occupancy grid per θ slice.
//! Everything outside the grid counts as an obstacle: an arena image ends
//! at the arena's walls.

use super::distance::FAR;
use super::grid::{CSpaceError, Grid, MAX_CELLS};
use crate::{Point, Shape};

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
    use image::GrayImage;

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
