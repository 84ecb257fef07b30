//! Pictures over a map, as SVG. A plan: obstacles black, what the robot's
//! size adds grey, the descent's cells blue, the smooth path red, start and
//! goal as rings. A run (thesis §7.4.2): the planned path, the path as the
//! Host estimated it and, in simulation, the true one.

use std::fmt::Write as _;

use crate::{Arena, CSpace, CSpaceError, Grid, PathAnalysis, Plan, Point, Pose};

/// An SVG's opening for a `w` × `h` mm floor, 900 px on its longer side.
fn open(w: f64, h: f64) -> String {
    let scale = 900.0 / w.max(h);
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0}\" height=\"{:.0}\" viewBox=\"0 0 {w} {h}\" shape-rendering=\"crispEdges\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n",
        w * scale,
        h * scale
    )
}

/// The cells of `grid` that `keep` picks, as horizontal runs filled with `fill`.
/// Rows of the image run down, as SVG's y does: cell row r is at y = r·S.
fn runs(grid: &Grid, keep: &dyn Fn(usize) -> bool, fill: &str, out: &mut String) {
    let s = grid.cell_mm;
    for r in 0..grid.height {
        let mut c = 0;
        while c < grid.width {
            if keep(grid.index(c, r)) {
                let first = c;
                while c < grid.width && keep(grid.index(c, r)) {
                    c += 1;
                }
                let _ = writeln!(
                    out,
                    "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{s}\" fill=\"{fill}\"/>",
                    f64::from(first) * s,
                    f64::from(r) * s,
                    f64::from(c - first) * s
                );
            }
            c += 1;
        }
    }
}

/// A polyline through `points` (floor mm, y up) on a floor `h` mm high.
fn polyline(points: &[Point], h: f64, colour: &str, width: f64, dash: Option<f64>) -> String {
    let d: Vec<String> = points
        .iter()
        .map(|p| format!("{:.2},{:.2}", p.x_mm, h - p.y_mm))
        .collect();
    let dash = dash.map_or(String::new(), |d| format!(" stroke-dasharray=\"{d:.1}\""));
    format!(
        "<path d=\"M{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"{width:.2}\"{dash} shape-rendering=\"auto\"/>\n",
        d.join(" L")
    )
}

/// A run over its arena: the planned path blue, the path as estimated
/// orange and dashed, the true one green, with a legend.
pub fn run_svg(
    arena: &Arena,
    cell_mm: f64,
    planned: &[Point],
    run: &PathAnalysis,
) -> Result<String, CSpaceError> {
    let grid = Grid::from_arena(arena, cell_mm)?;
    let (w, h) = (arena.width_mm, arena.height_mm);
    let mut out = open(w, h);
    runs(&grid, &|i| grid.blocked[i], "black", &mut out);
    let line = w.max(h) / 300.0;
    let mut legend = Vec::new();
    for (points, colour, width, dash, name) in [
        (planned, "#3070ff", line * 1.5, None, "planned"),
        (&run.truth[..], "#20a040", line, None, "true"),
        (
            &run.estimated[..],
            "#ff8000",
            line,
            Some(line * 4.0),
            "estimated",
        ),
    ] {
        if points.len() >= 2 {
            out.push_str(&polyline(points, h, colour, width, dash));
            legend.push((colour, name));
        }
    }
    let size = w.max(h) / 45.0;
    for (i, (colour, name)) in legend.iter().enumerate() {
        let y = size * (1.5 + 1.2 * i as f64);
        let _ = writeln!(
            out,
            "<text x=\"{:.1}\" y=\"{y:.1}\" font-family=\"sans-serif\" font-size=\"{size:.1}\" fill=\"{colour}\" stroke=\"white\" stroke-width=\"{:.2}\" paint-order=\"stroke\">{name}</text>",
            size,
            size / 6.0
        );
    }
    out.push_str("</svg>\n");
    Ok(out)
}

/// The plan (or only the map, start and goal when there is no path) drawn
/// on `workspace`, the map before growing, with `cspace` grown from it.
pub fn plan_svg(
    workspace: &Grid,
    cspace: &CSpace,
    start: Pose,
    goal: Pose,
    plan: Option<&Plan>,
) -> String {
    let (w, h) = workspace.size_mm();
    let s = workspace.cell_mm;
    let mut out = open(w, h);
    let grown = &cspace.slices[cspace.slice_of(start.theta_rad)];
    runs(
        grown,
        &|i| grown.blocked[i] && !workspace.blocked[i],
        "#c8c8c8",
        &mut out,
    );
    runs(workspace, &|i| workspace.blocked[i], "black", &mut out);
    let y = |y_mm: f64| h - y_mm;
    if let Some(plan) = plan {
        let cells: Vec<String> = plan
            .grid_path
            .iter()
            .map(|&(c, r, _)| {
                let p = workspace.centre(c, r);
                format!("{:.2},{:.2}", p.x_mm, y(p.y_mm))
            })
            .collect();
        let _ = writeln!(
            out,
            "<path d=\"M{}\" fill=\"none\" stroke=\"#3070ff\" stroke-width=\"{:.2}\" shape-rendering=\"auto\"/>",
            cells.join(" L"),
            s * 0.6
        );
        let width = (w.max(h) / 300.0).max(s * 0.3);
        out.push_str(&polyline(&plan.points(), h, "#e02020", width, None));
    }
    let mark = (w.max(h) / 80.0).max(s);
    for (pose, colour) in [(start, "#20a040"), (goal, "#e02020")] {
        let _ = writeln!(
            out,
            "<circle cx=\"{:.2}\" cy=\"{:.2}\" r=\"{mark:.2}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"{:.2}\"/>",
            pose.x_mm,
            y(pose.y_mm),
            mark / 3.0
        );
    }
    out.push_str("</svg>\n");
    out
}
