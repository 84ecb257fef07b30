//! A plan as people and programs read it (`vl plan`).

use serde::Serialize;

use super::cspace::CSpace;
use super::plan::{NoPath, Plan, Smoothing};
use vl_report::table::{Report, Table, count};

/// A plan as `vl plan` prints it: the grid, the paths on it and in mm,
/// their length and clearance; or why there is none.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct PlanReport {
    pub found: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    pub grid: GridInfo,
    pub nf1_start_value: Option<u32>,
    pub grid_path: Vec<[u32; 2]>,
    /// Heading slice of each grid path cell, when the C-space has several.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub grid_path_slices: Vec<u32>,
    pub path: Vec<[f64; 2]>,
    /// The planned heading at each sample, for a polygon robot.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub path_theta: Vec<f64>,
    pub smoothing: Option<Smoothing>,
    pub length_mm: Option<f64>,
    pub min_clearance_mm: Option<f64>,
    pub seconds: f64,
}

/// The grid a plan was made on.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct GridInfo {
    pub width: u32,
    pub height: u32,
    pub cell_mm: f64,
    pub theta_slices: usize,
}

impl PlanReport {
    /// `plan` on `cspace` (none: the start and goal are not connected),
    /// found in `seconds`.
    pub fn of(cspace: &CSpace, plan: Option<&Plan>, seconds: f64) -> PlanReport {
        let grid = cspace.grid();
        let sliced = cspace.slices.len() > 1;
        PlanReport {
            found: plan.is_some(),
            reason: plan.is_none().then(|| NoPath::Disconnected.to_string()),
            grid: GridInfo {
                width: grid.width,
                height: grid.height,
                cell_mm: grid.cell_mm,
                theta_slices: cspace.slices.len(),
            },
            nf1_start_value: plan.map(|p| p.nf1_start_value),
            grid_path: plan
                .map(|p| p.grid_path.iter().map(|&(c, r, _)| [c, r]).collect())
                .unwrap_or_default(),
            grid_path_slices: plan
                .filter(|_| sliced)
                .map(|p| p.grid_path.iter().map(|&(_, _, k)| k).collect())
                .unwrap_or_default(),
            path: plan
                .map(|p| p.path.iter().map(|q| [q.x_mm, q.y_mm]).collect())
                .unwrap_or_default(),
            path_theta: plan
                .filter(|_| sliced)
                .map(|p| p.path.iter().map(|q| q.theta_rad).collect())
                .unwrap_or_default(),
            smoothing: plan.map(|p| p.smoothing),
            length_mm: plan.map(|p| p.length_mm),
            min_clearance_mm: plan.map(|p| p.min_clearance_mm),
            seconds,
        }
    }
}

impl Report for PlanReport {
    fn table(&self) -> Table {
        let g = &self.grid;
        let mut rows = vec![(
            "grid",
            format!(
                "{} × {} cells of {} mm, {}",
                g.width,
                g.height,
                g.cell_mm,
                count(g.theta_slices as u64, "θ slice", "θ slices")
            ),
        )];
        if let Some(reason) = &self.reason {
            rows.push(("no path", reason.clone()));
        }
        if let (Some(v), Some(len), Some(clear)) =
            (self.nf1_start_value, self.length_mm, self.min_clearance_mm)
        {
            rows.push(("NF1 at start", count(v, "step", "steps")));
            rows.push((
                "grid path",
                count(self.grid_path.len() as u64, "cell", "cells"),
            ));
            rows.push((
                "smooth path",
                format!(
                    "{}, {len:.1} mm",
                    count(self.path.len() as u64, "sample", "samples")
                ),
            ));
            // Not the body's distance from obstacles (the window's "keeps"):
            // how far the centre may stray off the path before the C-space,
            // whose obstacles are grown by the body and the margin, blocks it.
            rows.push((
                "room to stray",
                format!(
                    "{clear:.1} mm at the closest, in the C-space (obstacles grown by the body)"
                ),
            ));
        }
        rows.push(("planned in", format!("{:.2} ms", self.seconds * 1e3)));
        Table::pairs(rows)
    }
}
