//! `vl sim …`: the simulator's tools.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use vl_core::Point;
use vl_sim::{Driver, LinkReport, Optics, Profile, WheelSchedule, World};

use crate::input::{RobotArgs, load_arena, load_target, positive};
use crate::report::emit;
use crate::shipped::read_input;
use crate::{BadInput, bad_input, named};

#[derive(Subcommand)]
pub(crate) enum SimCommand {
    /// Run the simulated robot in virtual time and print where it ended and
    /// a hash of the whole trace (same seed and script, same hash).
    Run {
        /// A shipped arena (navigation, corridor, open, maze) or an arena JSON file.
        #[arg(long, default_value = "navigation")]
        arena: String,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Simulated seconds to run at most (default: twice what the path
        /// takes at cruising speed plus 5 s; a script's last line plus 10 s).
        #[arg(long)]
        duration: Option<f64>,
        /// Lines of 't_s left_mm_s right_mm_s'. Without one the robot plans
        /// a path to the goal and follows it, and the run ends when it
        /// arrives; with no goal either, it stays put.
        #[arg(long)]
        script: Option<PathBuf>,
        /// Where to go, x,y mm (default: the goal the arena suggests).
        #[arg(long, conflicts_with = "script", allow_hyphen_values = true)]
        goal: Option<Point>,
        #[command(flatten)]
        robot: RobotArgs,
        #[arg(long)]
        json: bool,
    },
    /// Render one overhead camera frame of an arena to a PNG.
    Render {
        /// A shipped arena (navigation, corridor, open, maze) or an arena JSON file.
        #[arg(long, default_value = "navigation")]
        arena: String,
        #[arg(long, default_value_t = 320)]
        width: u32,
        #[command(flatten)]
        robot: RobotArgs,
        #[command(flatten)]
        optics: crate::options::OpticsArgs,
        /// Seed of the camera noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Instead of the arena, a calibration dot target (JSON, as `vl
        /// camera calibrate --target` takes) laid on its empty floor.
        #[arg(long)]
        target: Option<PathBuf>,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Real-time factor of the simulator, with and without the camera.
    Bench {
        /// Simulated seconds per measurement.
        #[arg(long, default_value_t = 600.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
    /// Measure how far the simulated robot's odometry drifts: UMBmark
    /// squares both ways, and each wheel's slip per √mm fitted to them.
    Odometry {
        /// Squares driven.
        #[arg(long, default_value_t = 400, value_parser = clap::value_parser!(u64).range(2..=100_000))]
        squares: u64,
        #[command(flatten)]
        robot: RobotArgs,
        #[arg(long)]
        json: bool,
    },
    /// Send packets through a modelled link and measure what they went through.
    Link {
        #[arg(long, value_parser = named::<Profile>())]
        profile: Profile,
        #[arg(long, default_value_t = 100_000)]
        packets: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Milliseconds between packets.
        #[arg(long, default_value_t = 10.0)]
        interval_ms: f64,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) fn run(command: SimCommand) -> Result<ExitCode> {
    match command {
        SimCommand::Run {
            arena,
            seed,
            duration,
            script,
            goal,
            robot,
            json,
        } => {
            let world = World::new(load_arena(&arena)?, robot.model()?, seed).map_err(bad_input)?;
            sim_run(world, duration, script.as_deref(), goal, json)
        }
        SimCommand::Render {
            arena,
            width,
            robot,
            optics,
            seed,
            target,
            output,
        } => {
            let optics = optics.optics(seed).map_err(bad_input)?;
            let world = World::new(load_arena(&arena)?, robot.model()?, seed).map_err(bad_input)?;
            let target = target.as_deref().map(load_target).transpose()?;
            render(&world, width, &optics, target.as_ref(), &output)
        }
        SimCommand::Bench { seconds, json } => {
            positive("--seconds", seconds)?;
            emit(&vl_sim::bench(seconds)?, json)?;
            Ok(ExitCode::SUCCESS)
        }
        SimCommand::Odometry {
            squares,
            robot,
            json,
        } => {
            emit(
                &vl_sim::measure_odometry(&robot.model()?, squares as usize)?,
                json,
            )?;
            Ok(ExitCode::SUCCESS)
        }
        SimCommand::Link {
            profile,
            packets,
            seed,
            interval_ms,
            json,
        } => {
            positive("--interval-ms", interval_ms)?;
            emit(
                &LinkReport::measure(profile, packets, interval_ms, seed),
                json,
            )?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn sim_run(
    mut world: World,
    duration: Option<f64>,
    script: Option<&Path>,
    goal: Option<Point>,
    json: bool,
) -> Result<ExitCode> {
    let mut driver = match script {
        Some(path) => {
            let text = read_input(path)?;
            Driver::WheelSchedule(
                WheelSchedule::parse(&text)
                    .map_err(|e| BadInput(format!("{}: {e}", path.display())))?,
            )
        }
        None => Driver::to_goal(&world, goal)
            .map_err(|e| BadInput(format!("no path to follow: {e}")))?,
    };
    let duration = duration.unwrap_or_else(|| driver.duration_s());
    if !(duration.is_finite() && duration >= 0.0) {
        return Err(BadInput(format!(
            "--duration must be a non-negative number of seconds, not {duration}"
        ))
        .into());
    }
    emit(&vl_sim::run(&mut world, &mut driver, duration), json)?;
    Ok(ExitCode::SUCCESS)
}

fn render(
    world: &World,
    width: u32,
    optics: &Optics,
    target: Option<&vl_core::DotTarget>,
    output: &Path,
) -> Result<ExitCode> {
    let (image, camera) = world.overhead_view(width, optics, target);
    image
        .save(output)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", output.display()))?;
    println!(
        "{}×{} px, {:.3} mm per px at the centre; wrote {}",
        camera.width_px,
        camera.height_px,
        camera.mm_per_px(),
        output.display()
    );
    Ok(ExitCode::SUCCESS)
}
