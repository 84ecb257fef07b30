//! A picture of a plan over its map, as SVG: obstacles black, what the
//! robot's size adds grey, the descent's cells blue, the smooth path red,
//! start and goal as rings.

use std::fmt::Write as _;

use crate::{CSpace, Grid, Plan, Pose};

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
    let scale = 900.0 / w.max(h);
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0}\" height=\"{:.0}\" viewBox=\"0 0 {w} {h}\" shape-rendering=\"crispEdges\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n",
        w * scale,
        h * scale
    );
    // Rows of the image run down, as SVG's y does: cell row r is at y = r·S.
    let runs = |grid: &Grid, keep: &dyn Fn(usize) -> bool, fill: &str, out: &mut String| {
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
    };
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
        let samples: Vec<String> = plan
            .path
            .iter()
            .map(|p| format!("{:.2},{:.2}", p.x_mm, y(p.y_mm)))
            .collect();
        let _ = writeln!(
            out,
            "<path d=\"M{}\" fill=\"none\" stroke=\"#3070ff\" stroke-width=\"{:.2}\" shape-rendering=\"auto\"/>",
            cells.join(" L"),
            s * 0.6
        );
        let _ = writeln!(
            out,
            "<path d=\"M{}\" fill=\"none\" stroke=\"#e02020\" stroke-width=\"{:.2}\" shape-rendering=\"auto\"/>",
            samples.join(" L"),
            (w.max(h) / 300.0).max(s * 0.3)
        );
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
