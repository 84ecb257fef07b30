//! `vl plan …`: plan a path on a top-view map (C-space, NF1, descent,
//! spline, clearance), as lab staff do to calibrate and as the mobile
//! robotics lab does for a user; and `vl plan bench`, its speed.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use serde::Serialize;
use vl_core::arena::Shape;
use vl_core::cspace::{CSpace, Footprint, Grid};
use vl_core::nf1::Nf1;
use vl_core::plan::{NoPath, Plan, clearance, locate, plan, smooth};
use vl_core::robot::{Point, Pose, RobotModel};
use vl_core::vision::Connectivity;

use crate::BadInput;

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct PlanArgs {
    #[command(subcommand)]
    command: Option<PlanCommand>,
    /// Top-view map image: pixels darker than --threshold are obstacles.
    #[arg(long, required = true)]
    map: Option<PathBuf>,
    /// The map's scale, mm per pixel.
    #[arg(long, required = true, allow_negative_numbers = true)]
    mm_per_px: Option<f64>,
    /// Where the robot starts: x,y[,θ] in mm and radians (θ from +x, counter-clockwise).
    #[arg(long, required = true, value_parser = parse_pose, allow_hyphen_values = true)]
    start: Option<Pose>,
    /// Where it should end: x,y[,θ].
    #[arg(long, required = true, value_parser = parse_pose, allow_hyphen_values = true)]
    goal: Option<Pose>,
    /// The robot as a disc of this radius, mm (0: a point on the map as is).
    /// The default is the Khepera II's.
    #[arg(long, conflicts_with = "footprint", allow_negative_numbers = true)]
    robot_radius: Option<f64>,
    /// The robot as a polygon instead, "x,y;x,y;…" mm in its own frame (x forward).
    #[arg(long, allow_hyphen_values = true)]
    footprint: Option<String>,
    /// Headings the C-space is sliced into for a polygon footprint.
    #[arg(long, default_value_t = 16)]
    theta_slices: u32,
    /// Grid steps: 4 (edges) or 8 (edges and corners).
    #[arg(long, default_value_t = 8)]
    connectivity: u8,
    /// Obstacles that are only in software, mm: rect:X,Y,W,H (bottom-left
    /// corner), circle:X,Y,R or polygon:X,Y;X,Y;…  Repeatable.
    #[arg(long = "virtual-obstacle", value_parser = parse_shape, allow_hyphen_values = true)]
    virtual_obstacles: Vec<Shape>,
    /// Cell size, mm (default: one pixel of the map).
    #[arg(long, allow_negative_numbers = true)]
    cell_mm: Option<f64>,
    /// Grey level below which a map pixel is an obstacle.
    #[arg(long, default_value_t = 128)]
    threshold: u8,
    #[arg(long)]
    json: bool,
    /// Also draw the map, C-space, grid path and smooth path here.
    #[arg(long)]
    svg: Option<PathBuf>,
}

#[derive(Subcommand)]
enum PlanCommand {
    /// Time NF1, descent and spline on a generated map, many runs.
    Bench {
        /// Cells on a side of the square map.
        #[arg(long, default_value_t = 1000)]
        size: u32,
        #[arg(long, default_value_t = 20)]
        runs: u32,
        #[arg(long)]
        json: bool,
    },
}

fn parse_numbers(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|n| {
            let v: f64 = n
                .trim()
                .parse()
                .map_err(|_| format!("'{n}' is not a number"))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("'{n}' is not a finite number"))
            }
        })
        .collect()
}

fn parse_pose(text: &str) -> Result<Pose, String> {
    match *parse_numbers(text)?.as_slice() {
        [x_mm, y_mm] => Ok(Pose {
            x_mm,
            y_mm,
            theta_rad: 0.0,
        }),
        [x_mm, y_mm, theta_rad] => Ok(Pose {
            x_mm,
            y_mm,
            theta_rad,
        }),
        _ => Err(format!("expected x,y or x,y,θ, not '{text}'")),
    }
}

fn parse_points(text: &str) -> Result<Vec<Point>, String> {
    text.split(';')
        .map(|pair| match *parse_numbers(pair)?.as_slice() {
            [x_mm, y_mm] => Ok(Point { x_mm, y_mm }),
            _ => Err(format!("expected a point x,y, not '{pair}'")),
        })
        .collect()
}

fn parse_shape(text: &str) -> Result<Shape, String> {
    let (kind, numbers) = text
        .split_once(':')
        .ok_or_else(|| format!("expected rect:…, circle:… or polygon:…, not '{text}'"))?;
    let shape = match kind {
        "rect" => match *parse_numbers(numbers)?.as_slice() {
            [x_mm, y_mm, width_mm, height_mm] => Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            },
            _ => return Err(format!("rect needs X,Y,W,H, not '{numbers}'")),
        },
        "circle" => match *parse_numbers(numbers)?.as_slice() {
            [x_mm, y_mm, radius_mm] => Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            },
            _ => return Err(format!("circle needs X,Y,R, not '{numbers}'")),
        },
        "polygon" => Shape::Polygon {
            points: parse_points(numbers)?,
        },
        other => {
            return Err(format!(
                "unknown shape '{other}': use rect, circle or polygon"
            ));
        }
    };
    shape.check()?;
    Ok(shape)
}

pub fn run(args: PlanArgs) -> Result<ExitCode> {
    if let Some(PlanCommand::Bench { size, runs, json }) = args.command {
        return bench(size, runs, json);
    }
    let (Some(map), Some(mm_per_px), Some(start), Some(goal)) =
        (&args.map, args.mm_per_px, args.start, args.goal)
    else {
        return Err(BadInput("vl plan needs --map, --mm-per-px, --start and --goal".into()).into());
    };
    let connectivity = match args.connectivity {
        4 => Connectivity::Four,
        8 => Connectivity::Eight,
        n => return Err(BadInput(format!("--connectivity must be 4 or 8, not {n}")).into()),
    };
    let footprint = match (&args.footprint, args.robot_radius) {
        (Some(text), _) => Footprint::Polygon {
            points: parse_points(text).map_err(|e| BadInput(format!("--footprint: {e}")))?,
        },
        (None, radius) => Footprint::Disc {
            radius_mm: radius.unwrap_or_else(|| RobotModel::khepera_ii().radius_mm),
        },
    };
    let image = load_grey(map)?;
    let started = Instant::now();
    let mut workspace = Grid::from_image(
        &image,
        args.threshold,
        mm_per_px,
        args.cell_mm.unwrap_or(mm_per_px),
    )
    .map_err(|e| BadInput(format!("--mm-per-px/--cell-mm: {e}")))?;
    for shape in &args.virtual_obstacles {
        workspace.block(shape);
    }
    let cspace = CSpace::build(&workspace, footprint, args.theta_slices)
        .map_err(|e| BadInput(e.to_string()))?;
    let result = plan(&cspace, start, goal, connectivity);
    let seconds = started.elapsed().as_secs_f64();
    let plan = match result {
        Ok(plan) => Some(plan),
        Err(NoPath::Disconnected) => None,
        Err(e) => return Err(BadInput(format!("no path: {e}")).into()),
    };
    if let Some(path) = &args.svg {
        std::fs::write(path, svg(&workspace, &cspace, start, goal, plan.as_ref()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let report = Report::new(&cspace, plan.as_ref(), seconds);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report);
    }
    Ok(ExitCode::SUCCESS)
}

fn load_grey(path: &Path) -> Result<image::GrayImage> {
    let image = image::open(path)
        .map_err(|e| BadInput(format!("cannot read the map image {}: {e}", path.display())))?;
    Ok(vl_core::vision::grey(&image.to_rgb8()))
}

/// What `vl plan` prints; `--json` gives it whole.
#[derive(Serialize)]
struct Report {
    found: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<String>,
    grid: GridInfo,
    nf1_start_value: Option<u32>,
    grid_path: Vec<[u32; 2]>,
    /// Heading slice of each grid path cell, when the C-space has several.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    grid_path_slices: Vec<u32>,
    path: Vec<[f64; 2]>,
    /// The planned heading at each sample, for a polygon robot.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    path_theta: Vec<f64>,
    smoothing: Option<vl_core::plan::Smoothing>,
    length_mm: Option<f64>,
    min_clearance_mm: Option<f64>,
    seconds: f64,
}

#[derive(Serialize)]
struct GridInfo {
    width: u32,
    height: u32,
    cell_mm: f64,
    theta_slices: usize,
}

impl Report {
    fn new(cspace: &CSpace, plan: Option<&Plan>, seconds: f64) -> Report {
        let grid = cspace.grid();
        let sliced = cspace.slices.len() > 1;
        Report {
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

fn print_report(report: &Report) {
    let g = &report.grid;
    println!(
        "grid          {} × {} cells of {} mm, {} θ slice(s)",
        g.width, g.height, g.cell_mm, g.theta_slices
    );
    if let Some(reason) = &report.reason {
        println!("no path       {reason}");
    }
    if let (Some(v), Some(len), Some(clear)) = (
        report.nf1_start_value,
        report.length_mm,
        report.min_clearance_mm,
    ) {
        println!("NF1 at start  {v} steps");
        println!("grid path     {} cells", report.grid_path.len());
        println!("smooth path   {} samples, {len:.1} mm", report.path.len());
        println!("clearance     {clear:.1} mm at the closest");
    }
    println!("planned in    {:.2} ms", report.seconds * 1e3);
}

/// The plan over its map: obstacles black, what the robot's size adds
/// grey, the descent's cells blue, the smooth path red.
fn svg(workspace: &Grid, cspace: &CSpace, start: Pose, goal: Pose, plan: Option<&Plan>) -> String {
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

/// A square map of `size` cells with walls across it, each with a gap at
/// alternate ends (so the path snakes), and scattered blocks between.
fn bench_map(size: u32) -> Result<Grid> {
    let mut grid = Grid::free(size, size, 1.0).map_err(|e| BadInput(format!("--size: {e}")))?;
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

#[derive(Serialize)]
struct BenchReport {
    size: u32,
    runs: u32,
    path_cells: usize,
    /// Median milliseconds of each stage.
    cspace_ms: f64,
    nf1_ms: f64,
    descent_ms: f64,
    spline_ms: f64,
    clearance_ms: f64,
    /// NF1 + descent + spline.
    plan_ms: f64,
}

fn bench(size: u32, runs: u32, json: bool) -> Result<ExitCode> {
    if size < 50 {
        return Err(BadInput(format!("--size must be at least 50 cells, not {size}")).into());
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
    let mut stages: [Vec<f64>; 5] = Default::default();
    let mut path_cells = 0;
    for run in 0..=runs {
        let mut cspace = None;
        let c_ms = time(&mut || cspace = Some(CSpace::build(&workspace, footprint.clone(), 1)));
        let cspace = cspace.expect("timed above")?;
        let from = locate(&cspace, start, vl_core::plan::End::Start)?;
        let to = locate(&cspace, goal, vl_core::plan::End::Goal)?;
        let mut nf1 = None;
        let n_ms = time(&mut || nf1 = Some(Nf1::from_goal(&cspace, to, Connectivity::Eight)));
        let nf1 = nf1.expect("timed above");
        let mut cells = None;
        let d_ms = time(&mut || cells = nf1.descend(from, to));
        let cells = cells.context("the bench map's start and goal are connected")?;
        let mut path = Vec::new();
        let s_ms = time(&mut || path = smooth(&cspace, start, goal, &cells).0);
        let mut clear = 0.0;
        let k_ms = time(&mut || clear = clearance(&cspace, &path));
        std::hint::black_box(clear);
        path_cells = cells.len();
        if run > 0 {
            // Run 0 warms caches and the allocator.
            for (stage, ms) in stages.iter_mut().zip([c_ms, n_ms, d_ms, s_ms, k_ms]) {
                stage.push(ms);
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut plan_ms: Vec<f64> = (0..runs as usize)
        .map(|i| stages[1][i] + stages[2][i] + stages[3][i])
        .collect();
    let report = BenchReport {
        size,
        runs,
        path_cells,
        cspace_ms: median(&mut stages[0]),
        nf1_ms: median(&mut stages[1]),
        descent_ms: median(&mut stages[2]),
        spline_ms: median(&mut stages[3]),
        clearance_ms: median(&mut stages[4]),
        plan_ms: median(&mut plan_ms),
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{0} × {0} map, path of {1} cells, median of {2} runs:",
            size, report.path_cells, runs
        );
        for (name, ms) in [
            ("C-space (disc)", report.cspace_ms),
            ("NF1 wavefront", report.nf1_ms),
            ("descent", report.descent_ms),
            ("spline + check", report.spline_ms),
            ("clearance", report.clearance_ms),
            ("NF1+descent+spline", report.plan_ms),
        ] {
            println!("  {name:<20} {ms:>8.2} ms");
        }
    }
    Ok(ExitCode::SUCCESS)
}
