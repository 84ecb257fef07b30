//! How fast planning is: each stage timed on a generated map with a long,
//! snaking path, median of many runs (`vl plan bench`).

use std::time::Instant;

use serde::Serialize;
use thiserror::Error;
use vl_report::table::{Report, Table, count};

use super::plan::{locate, plan, smooth};
use crate::{
    CSpace, CSpaceError, Connectivity, Footprint, Grid, Nf1, NoPath, PathEnd, Pose, Shape,
    clearance,
};

/// The smallest map the benchmark's walls and gaps fit on, cells a side.
pub(crate) const MIN_BENCH_CELLS: u32 = 50;

/// Median milliseconds of each planning stage.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct PlanBench {
    pub size: u32,
    pub runs: u32,
    pub path_cells: usize,
    pub cspace_ms: f64,
    pub nf1_ms: f64,
    pub descent_ms: f64,
    pub spline_ms: f64,
    pub clearance_ms: f64,
    /// The whole plan timed as one job: C-space, then [`plan`] (NF1,
    /// descent, spline and clearance).
    pub whole_ms: f64,
}

#[derive(Debug, Error)]
pub enum PlanBenchError {
    #[error("the benchmark map must be at least {MIN_BENCH_CELLS} cells a side, not {0}")]
    TooSmall(u32),
    #[error(transparent)]
    Map(#[from] CSpaceError),
    #[error(transparent)]
    NoPath(#[from] NoPath),
}

/// A square map of `size` cells with walls across it, each with a gap at
/// alternate ends (so the path snakes), and scattered blocks between.
fn bench_map(size: u32) -> Result<Grid, CSpaceError> {
    let mut grid = Grid::free(size, size, 1.0)?;
    let walls = 6;
    for k in 1..=walls {
        let row = size * k / (walls + 1);
        let gap = size / 8;
        let (from, to) = if k % 2 == 0 {
            (0, size - gap)
        } else {
            (gap, size)
        };
        for r in row..(row + size / 100).min(size) {
            for c in from..to {
                let i = grid.index(c, r);
                grid.blocked[i] = true;
            }
        }
    }
    // Blocks on a fixed pseudo-random lattice (a linear congruential sequence).
    let mut x: u64 = 1;
    for _ in 0..size / 4 {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let (c, r) = ((x >> 33) as u32 % size, (x >> 13) as u32 % size);
        grid.block(&Shape::Circle {
            x_mm: f64::from(c),
            y_mm: f64::from(r),
            radius_mm: f64::from(size) / 120.0,
        });
    }
    Ok(grid)
}

/// Times each stage on a `size` × `size` map, `runs` times after one
/// warm-up run, and reports the medians.
pub fn bench(size: u32, runs: u32) -> Result<PlanBench, PlanBenchError> {
    if size < MIN_BENCH_CELLS {
        return Err(PlanBenchError::TooSmall(size));
    }
    let runs = runs.max(1);
    let workspace = bench_map(size)?;
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        t.elapsed().as_secs_f64() * 1e3
    };
    let footprint = Footprint::Disc {
        radius_mm: f64::from(size) / 200.0,
    };
    let margin = f64::from(size) / 25.0;
    let start = Pose {
        x_mm: margin,
        y_mm: margin,
        theta_rad: 0.0,
    };
    let goal = Pose {
        x_mm: f64::from(size) - margin,
        y_mm: f64::from(size) - margin,
        theta_rad: 0.0,
    };
    let mut stages: [Vec<f64>; 6] = Default::default();
    let mut path_cells = 0;
    for run in 0..=runs {
        let mut cspace = None;
        let c_ms = time(&mut || cspace = Some(CSpace::build(&workspace, footprint.clone(), 1)));
        let cspace = cspace.expect("timed above")?;
        let from = locate(&cspace, start, PathEnd::Start)?;
        let to = locate(&cspace, goal, PathEnd::Goal)?;
        let mut nf1 = None;
        let n_ms = time(&mut || nf1 = Some(Nf1::toward(&cspace, to, from, Connectivity::Eight)));
        let nf1 = nf1.expect("timed above");
        let mut cells = None;
        let d_ms = time(&mut || cells = nf1.descend(from, to));
        let cells = cells.ok_or(NoPath::Disconnected)?;
        let mut path = Vec::new();
        let s_ms = time(&mut || path = smooth(&cspace, start, goal, &cells).0);
        let mut clear = 0.0;
        let k_ms = time(&mut || clear = clearance(&cspace, &path));
        std::hint::black_box(clear);
        path_cells = cells.len();
        let mut whole = None;
        let w_ms = time(&mut || {
            whole = Some(
                CSpace::build(&workspace, footprint.clone(), 1)
                    .map_err(PlanBenchError::from)
                    .and_then(|cspace| Ok(plan(&cspace, start, goal, Connectivity::Eight)?)),
            );
        });
        std::hint::black_box(whole.expect("timed above")?);
        if run > 0 {
            // Run 0 warms caches and the allocator.
            for (stage, ms) in stages.iter_mut().zip([c_ms, n_ms, d_ms, s_ms, k_ms, w_ms]) {
                stage.push(ms);
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    Ok(PlanBench {
        size,
        runs,
        path_cells,
        cspace_ms: median(&mut stages[0]),
        nf1_ms: median(&mut stages[1]),
        descent_ms: median(&mut stages[2]),
        spline_ms: median(&mut stages[3]),
        clearance_ms: median(&mut stages[4]),
        whole_ms: median(&mut stages[5]),
    })
}

impl Report for PlanBench {
    fn table(&self) -> Table {
        let mut table = Table::columns(&["stage", "median ms"]).title(format!(
            "{0} × {0} map, path of {1} cells, median of {2}:",
            self.size,
            self.path_cells,
            count(self.runs, "run", "runs")
        ));
        for (name, ms) in [
            ("C-space (disc)", self.cspace_ms),
            ("NF1 wavefront", self.nf1_ms),
            ("descent", self.descent_ms),
            ("spline + check", self.spline_ms),
            ("clearance", self.clearance_ms),
            ("whole plan", self.whole_ms),
        ] {
            table.row(vec![name.to_owned(), format!("{ms:.2}")]);
        }
        table
    }
}
