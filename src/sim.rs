//! `vl sim …`: the simulator's tools.

use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

use vl_core::arena::Arena;
use vl_core::follow::{Follower, Following, PLAN_MARGIN_MM};
use vl_core::plan::plan_in_arena;
use vl_core::robot::{Point, RobotModel};
use vl_sim::link::{Link, LinkModel, LinkStats, measure};
use vl_sim::script::{Driver, Script, run as run_script};
use vl_sim::{Optics, World, camera_for};

use crate::{BadInput, read_input};

/// Which robot to simulate, and its size if not the stock one.
#[derive(clap::Args)]
pub struct RobotArgs {
    /// khepera-ii or khepera-i.
    #[arg(long, default_value = "khepera-ii")]
    robot: String,
    /// Build the robot with this body radius, mm (sensors move out with it).
    #[arg(long, requires = "wheel_base_mm")]
    radius_mm: Option<f64>,
    /// … and this distance between its wheels, mm.
    #[arg(long, requires = "radius_mm")]
    wheel_base_mm: Option<f64>,
}

impl RobotArgs {
    pub fn model(&self) -> Result<RobotModel> {
        let model = RobotModel::named(&self.robot).ok_or_else(|| {
            BadInput(format!(
                "unknown robot '{}' (known: khepera-ii, khepera-i)",
                self.robot
            ))
        })?;
        Ok(match (self.radius_mm, self.wheel_base_mm) {
            (Some(radius), Some(base)) => model.resized(radius, base).map_err(BadInput)?,
            _ => model,
        })
    }
}

/// How the simulated camera departs from an ideal one.
#[derive(clap::Args)]
pub struct OpticsArgs {
    /// Image shift in px, as DX,DY (lens off the sensor's axis).
    #[arg(long, value_parser = parse_pair, default_value = "0,0")]
    lens_offset: [f64; 2],
    /// Gaussian blur, standard deviation in px.
    #[arg(long, default_value_t = 0.0)]
    blur: f64,
    /// Per-pixel noise, standard deviation in grey levels.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// How much darker the bottom-right corner is (0–1).
    #[arg(long, default_value_t = 0.0)]
    lighting: f64,
}

fn parse_pair(text: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = text.split(',').collect();
    match parts.as_slice() {
        [a, b] => Ok([
            a.trim().parse().map_err(|e| format!("'{a}': {e}"))?,
            b.trim().parse().map_err(|e| format!("'{b}': {e}"))?,
        ]),
        _ => Err(format!("expected two numbers as DX,DY, not '{text}'")),
    }
}

#[derive(Subcommand)]
pub enum SimCommand {
    /// Run the simulated robot in virtual time and print where it ended and
    /// a hash of the whole trace (same seed and script, same hash).
    Run {
        /// A shipped arena (navigation, corridor, open, maze) or an arena JSON file.
        #[arg(long, default_value = "navigation")]
        arena: String,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long, default_value_t = 10.0)]
        duration: f64,
        /// Lines of 't_s left_mm_s right_mm_s'. Without one the robot plans
        /// a path to the goal and follows it, and the run ends when it
        /// arrives; with no goal either, it stays put.
        #[arg(long)]
        script: Option<PathBuf>,
        /// Where to go, x,y mm (default: the goal the arena suggests).
        #[arg(long, value_parser = parse_pair, conflicts_with = "script")]
        goal: Option<[f64; 2]>,
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
        optics: OpticsArgs,
        /// Seed of the camera noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
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
    /// Send packets through a modelled link and measure what they went through.
    Link {
        /// lan, internet2, internet-2005, intercontinental, congested or geo-satellite.
        #[arg(long)]
        profile: String,
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

pub fn run(command: SimCommand) -> Result<ExitCode> {
    match command {
        SimCommand::Run {
            arena,
            seed,
            duration,
            script,
            goal,
            robot,
            json,
        } => sim_run(
            World::new(arena_named(&arena)?, robot.model()?, seed)
                .map_err(|e| BadInput(e.to_string()))?,
            duration,
            script.as_deref(),
            goal,
            json,
        ),
        SimCommand::Render {
            arena,
            width,
            robot,
            optics,
            seed,
            output,
        } => {
            let optics = Optics {
                lens_offset_px: optics.lens_offset,
                blur_px: optics.blur,
                noise: optics.noise,
                lighting_gradient: optics.lighting,
                seed,
            };
            optics.check().map_err(BadInput)?;
            let world = World::new(arena_named(&arena)?, robot.model()?, seed)
                .map_err(|e| BadInput(e.to_string()))?;
            render(&world, width, &optics, &output)
        }
        SimCommand::Bench { seconds, json } => bench(seconds, json),
        SimCommand::Link {
            profile,
            packets,
            seed,
            interval_ms,
            json,
        } => link(&profile, packets, seed, interval_ms, json),
    }
}

/// Measured figures beside the ones the profile asks for.
#[derive(Serialize)]
struct LinkReport {
    profile: String,
    model: LinkModel,
    measured: LinkStats,
    expected: Expected,
}

#[derive(Serialize)]
struct Expected {
    delay_mean_ms: f64,
    jitter_ms: f64,
    loss_rate: f64,
    mean_loss_burst: f64,
}

fn link(
    profile: &str,
    packets: usize,
    seed: u64,
    interval_ms: f64,
    json: bool,
) -> Result<ExitCode> {
    let model = LinkModel::profile(profile).map_err(|e| BadInput(e.to_string()))?;
    let expected = Expected {
        delay_mean_ms: model.expected_delay(),
        jitter_ms: model.expected_jitter(),
        loss_rate: model.expected_loss(),
        mean_loss_burst: model.expected_burst(),
    };
    let mut link = Link::new(model.clone(), seed);
    let measured = measure(&mut link, packets, interval_ms, 100);
    if json {
        let report = LinkReport {
            profile: profile.to_owned(),
            model,
            measured,
            expected,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let m = &measured;
    println!("{profile}: {packets} packets, one every {interval_ms} ms, seed {seed}");
    println!("{:<18} {:>12} {:>12}", "", "measured", "profile");
    let rows = [
        ("delay mean, ms", m.delay_mean_ms, expected.delay_mean_ms),
        ("jitter (sd), ms", m.jitter_ms, expected.jitter_ms),
        (
            "loss rate, %",
            m.loss_rate * 100.0,
            expected.loss_rate * 100.0,
        ),
        ("loss burst", m.mean_loss_burst, expected.mean_loss_burst),
    ];
    for (name, got, want) in rows {
        println!("{name:<18} {got:>12.4} {want:>12.4}");
    }
    println!("{:<18} {:>12.3}", "delay p50, ms", m.delay_p50_ms);
    println!("{:<18} {:>12.3}", "delay p99, ms", m.delay_p99_ms);
    println!("{:<18} {:>12}", "duplicates", m.duplicates);
    println!("{:<18} {:>12}", "reorders", m.reorders);
    Ok(ExitCode::SUCCESS)
}

/// A shipped arena by name, or an arena file (JSON) by path.
pub fn arena_named(name_or_path: &str) -> Result<Arena> {
    if let Some(arena) = Arena::named(name_or_path) {
        return Ok(arena);
    }
    let path = Path::new(name_or_path);
    if path.extension().is_some_and(|e| e == "json") || path.exists() {
        let text = read_input(path)?;
        // A map image is named relative to the arena file.
        let dir = path.parent().unwrap_or(Path::new("."));
        let load = |image: &str| {
            let file = dir.join(image);
            image::open(&file)
                .map(|i| i.to_luma8())
                .map_err(|e| format!("cannot read the map image {}: {e}", file.display()))
        };
        return Ok(Arena::from_json_with(&text, load)
            .map_err(|e| BadInput(format!("{}: {e}", path.display())))?);
    }
    let known: Vec<&str> = Arena::shipped().collect();
    Err(BadInput(format!(
        "unknown arena '{name_or_path}' (shipped: {}; or a .json file)",
        known.join(", ")
    ))
    .into())
}

fn sim_run(
    mut world: World,
    duration: f64,
    script: Option<&Path>,
    goal: Option<[f64; 2]>,
    json: bool,
) -> Result<ExitCode> {
    if !(duration.is_finite() && duration >= 0.0) {
        return Err(BadInput(format!(
            "--duration must be a non-negative number of seconds, not {duration}"
        ))
        .into());
    }
    let mut driver = match script {
        Some(path) => {
            let text = read_input(path)?;
            Driver::Script(
                Script::parse(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?,
            )
        }
        None => follow_to(&world, goal)?,
    };
    let report = run_script(&mut world, &mut driver, duration);
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let p = report.final_pose;
        println!("{:<12} {:.2} s", "simulated", report.sim_seconds);
        println!(
            "{:<12} ({:.1}, {:.1}) mm, {:.1}°",
            "final pose",
            p.x_mm,
            p.y_mm,
            p.theta_rad.to_degrees()
        );
        println!("{:<12} {:.0} mm", "distance", report.distance_mm);
        if let Some(t) = report.following {
            println!(
                "{:<12} {} (path kept to within {:.1} mm on average, {:.1} mm at worst)",
                "goal",
                if t.reached_goal {
                    "reached"
                } else {
                    "not reached"
                },
                t.mean_error_mm,
                t.max_error_mm
            );
        }
        println!("{:<12} {}", "collisions", report.collisions);
        println!("{:<12} {}", "trace hash", report.trace_hash);
    }
    Ok(ExitCode::SUCCESS)
}

/// A follower for a path planned from the robot to `goal` (or the
/// arena's); idle when there is neither.
fn follow_to(world: &World, goal: Option<[f64; 2]>) -> Result<Driver> {
    let arena = world.arena();
    let goal = match (goal, arena.goal) {
        (Some([x_mm, y_mm]), _) => Point { x_mm, y_mm },
        (None, Some(goal)) => goal,
        (None, None) => return Ok(Driver::Idle),
    };
    let plan = plan_in_arena(
        arena,
        &[],
        world.robot().radius_mm,
        PLAN_MARGIN_MM,
        world.pose(),
        goal,
    )
    .map_err(|e| BadInput(format!("no path to follow: {e}")))?;
    let path = plan.points();
    let follower = Follower::new(path, Following::default()).expect("a plan has samples");
    Ok(Driver::Path(follower))
}

fn render(world: &World, width: u32, optics: &Optics, output: &Path) -> Result<ExitCode> {
    let camera = camera_for(world, width.max(1), 15.0);
    world
        .render(&camera, optics)
        .save(output)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", output.display()))?;
    println!(
        "{}×{} px, {} mm per px; wrote {}",
        camera.width_px,
        camera.height_px,
        camera.mm_per_px,
        output.display()
    );
    Ok(ExitCode::SUCCESS)
}

#[derive(Serialize)]
struct BenchReport {
    sim_seconds: f64,
    /// Simulated seconds per wall-clock second, robot and sensors only.
    rtf_no_camera: f64,
    /// The same with a 320×240 camera frame rendered at 30 Hz.
    rtf_camera: f64,
}

fn bench(seconds: f64, json: bool) -> Result<ExitCode> {
    let timed = |camera_hz: Option<f64>| -> Result<f64> {
        let mut world = World::new(Arena::navigation(), RobotModel::khepera_ii(), 1)?;
        let camera = camera_for(&world, 320, 30.0);
        let frame_every = camera_hz.map(|hz| ((1.0 / hz) / vl_sim::STEP_S).round().max(1.0) as u64);
        let steps = (seconds / vl_sim::STEP_S) as u64;
        let started = Instant::now();
        let mut frames = 0usize;
        for step in 0..steps {
            if step % 2 == 0 {
                std::hint::black_box(world.proximity());
            }
            // A slow circle keeps the robot moving through the arena.
            world.set_wheels(vl_core::robot::WheelSpeeds {
                left_mm_s: 120.0,
                right_mm_s: 150.0,
            });
            world.step();
            if frame_every.is_some_and(|every| step % every == 0) {
                frames += std::hint::black_box(world.render(&camera, &Optics::default())).len();
            }
        }
        std::hint::black_box(frames);
        Ok(seconds / started.elapsed().as_secs_f64())
    };
    let report = BenchReport {
        sim_seconds: seconds,
        rtf_no_camera: timed(None)?,
        rtf_camera: timed(Some(30.0))?,
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{:<28} {:>12.0}×",
            "real-time factor, no camera", report.rtf_no_camera
        );
        println!(
            "{:<28} {:>12.0}×",
            "with 320×240 camera at 30 Hz", report.rtf_camera
        );
    }
    Ok(ExitCode::SUCCESS)
}
