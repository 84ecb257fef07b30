//! `vl plan …`: plan a path on a top-view map (C-space, NF1, descent,
//! spline, clearance), as lab staff do to calibrate and as the mobile
//! robotics lab does for a user; and `vl plan bench`, its speed.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use image::GrayImage;
use vl_core::{
    Arena, CSpace, Connectivity, Footprint, Grid, NoPath, PlanBenchError, PlanReport, Point, Pose,
    RobotModel, Shape, plan, plan_svg,
};

use crate::input::load_rgb;
use crate::report::emit;
use crate::{BadInput, bad_input, named};

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub(crate) struct PlanArgs {
    #[command(subcommand)]
    command: Option<PlanCommand>,
    /// Top-view map: an image file whose pixels darker than --threshold
    /// are obstacles, or the name of a shipped arena drawn as one (maze).
    #[arg(long, required = true)]
    map: Option<String>,
    /// The map's scale, mm per pixel.
    #[arg(long, required = true, allow_negative_numbers = true)]
    mm_per_px: Option<f64>,
    /// Where the robot starts: x,y[,θ] in mm and radians (θ from +x, counter-clockwise).
    #[arg(long, required = true, allow_hyphen_values = true)]
    start: Option<Pose>,
    /// Where it should end: x,y[,θ].
    #[arg(long, required = true, allow_hyphen_values = true)]
    goal: Option<Pose>,
    /// The robot as a disc of this radius, mm (0: a point on the map as is).
    /// The default is the Khepera II's.
    #[arg(long, conflicts_with = "footprint", allow_negative_numbers = true)]
    robot_radius: Option<f64>,
    /// The robot as a polygon instead, "x,y;x,y;…" mm in its own frame (x forward).
    #[arg(long, value_delimiter = ';', allow_hyphen_values = true)]
    footprint: Vec<Point>,
    /// Headings the C-space is sliced into for a polygon footprint.
    #[arg(long, default_value_t = 16)]
    theta_slices: u32,
    /// Grid steps: 4 (edges) or 8 (edges and corners).
    #[arg(long, value_parser = named::<Connectivity>(), default_value = "8")]
    connectivity: Connectivity,
    /// Obstacles that are only in software, mm: rect:X,Y,W,H (bottom-left
    /// corner), circle:X,Y,R or polygon:X,Y;X,Y;…  Repeatable.
    #[arg(long = "virtual-obstacle", allow_hyphen_values = true)]
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
pub(crate) enum PlanCommand {
    /// Time each planning stage, and the whole plan, on a generated map, many runs.
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

pub(crate) fn run(args: PlanArgs) -> Result<ExitCode> {
    if let Some(PlanCommand::Bench { size, runs, json }) = args.command {
        let report = vl_core::bench_planning(size, runs).map_err(|e| match e {
            PlanBenchError::TooSmall(_) => BadInput(format!("--size: {e}")).into(),
            other => anyhow::Error::from(other),
        })?;
        emit(&report, json)?;
        return Ok(ExitCode::SUCCESS);
    }
    let (Some(map), Some(mm_per_px), Some(start), Some(goal)) =
        (&args.map, args.mm_per_px, args.start, args.goal)
    else {
        return Err(BadInput("vl plan needs --map, --mm-per-px, --start and --goal".into()).into());
    };
    let footprint = match args.robot_radius {
        _ if !args.footprint.is_empty() => Footprint::Polygon {
            points: args.footprint.clone(),
        },
        radius => Footprint::Disc {
            radius_mm: radius.unwrap_or_else(|| RobotModel::khepera_ii().radius_mm),
        },
    };
    let image = load_map(map)?;
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
    let cspace = CSpace::build(&workspace, footprint, args.theta_slices).map_err(bad_input)?;
    let result = plan(&cspace, start, goal, args.connectivity);
    let seconds = started.elapsed().as_secs_f64();
    let plan = match result {
        Ok(plan) => Some(plan),
        Err(NoPath::Disconnected) => None,
        Err(e) => return Err(BadInput(format!("no path: {e}")).into()),
    };
    if let Some(path) = &args.svg {
        std::fs::write(
            path,
            plan_svg(&workspace, &cspace, start, goal, plan.as_ref()),
        )
        .with_context(|| format!("cannot write {}", path.display()))?;
    }
    emit(&PlanReport::of(&cspace, plan.as_ref(), seconds), args.json)?;
    Ok(ExitCode::SUCCESS)
}

/// The map in grey: a shipped arena's top view by name, or an image file.
fn load_map(name: &str) -> Result<GrayImage> {
    if let Some(map) = Arena::shipped_map(name) {
        return Ok(map);
    }
    Ok(vl_core::grey(&load_rgb(
        std::path::Path::new(name),
        "map image",
    )?))
}
