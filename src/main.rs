//! `vl`: the virtual laboratory's one binary. `vl host` serves the lab,
//! `vl guest` is the user's desktop app, `vl demo` runs both on the
//! simulated lab.

mod alloc;
mod petri;
mod plan;
mod sim;
mod vision;

use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use vl_core::arena::Arena;
use vl_core::protocol::Role;
use vl_core::robot::RobotModel;
use vl_guest::headless::{Report, Script, drive_to_goal};
use vl_host::khepera::KheperaSerial;
use vl_host::{Host, HostConfig};

#[derive(Parser)]
#[command(
    name = "vl",
    version,
    about = "A virtual laboratory for telerobotics over the Internet"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve the lab to Guests over WebSocket (on the lab machine).
    Host(HostArgs),
    /// Open the Guest window on a Host (on the user's desktop).
    Guest(GuestArgs),
    /// Run a Host on the simulated lab and a Guest against it, in one process.
    Demo(DemoArgs),
    /// Analyse Petri nets (PNML).
    #[command(subcommand)]
    Petri(petri::PetriCommand),
    /// Emulate a Khepera II on a pseudo-terminal, backed by the simulator.
    KheperaEmu(KheperaArgs),
    /// The simulator's tools: scripted runs, camera frames, link models, speed.
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// Vision on camera frames: components, moments, the robot's pose.
    #[command(subcommand)]
    Vision(vision::VisionCommand),
    /// Plan a path on a top-view map: C-space, NF1, spline, clearance.
    Plan(plan::PlanArgs),
}

#[derive(clap::Args)]
struct KheperaArgs {
    /// The arena the simulated robot drives in: a shipped one or a JSON file.
    #[arg(long, default_value = "navigation")]
    arena: String,
    #[command(flatten)]
    robot: sim::RobotArgs,
    /// The line speed to emulate (with --line-timing).
    #[arg(long, default_value_t = 38_400)]
    baud: u32,
    /// Also make a symlink to the device here.
    #[arg(long)]
    link: Option<std::path::PathBuf>,
    /// Delay replies by the time their characters take at --baud.
    #[arg(long)]
    line_timing: bool,
    /// Seed for the sensors' noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[global_allocator]
static ALLOCATOR: alloc::Counting = alloc::Counting;

/// A problem with what the user gave (a file, an argument): exit code 2.
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// The text of a file the user named; a missing or unreadable one is bad input.
pub fn read_input(path: &std::path::Path) -> Result<String> {
    std::fs::read_to_string(path)
        .map_err(|e| BadInput(format!("cannot read {}: {e}", path.display())).into())
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum RobotKind {
    /// The simulated Khepera II.
    Sim,
    /// A Khepera I/II on the serial line --port.
    Khepera,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum CameraKind {
    /// The simulated overhead camera (watches the simulated robot only).
    Sim,
    /// No camera: Guests get feedback but no frames.
    None,
}

#[derive(clap::Args)]
struct HostArgs {
    /// Which robot to drive.
    #[arg(long, value_enum, default_value = "sim")]
    robot: RobotKind,
    /// The serial device of a Khepera (with --robot khepera).
    #[arg(long, required_if_eq("robot", "khepera"))]
    port: Option<String>,
    /// The serial line's speed (with --robot khepera).
    #[arg(long, default_value_t = 38_400)]
    baud: u32,
    /// Which camera to watch the arena with; a real robot has no simulated
    /// camera, so the default there is none.
    #[arg(
        long,
        value_enum,
        default_value_if("robot", "khepera", "none"),
        default_value = "sim"
    )]
    camera: CameraKind,
    /// The arena the robot is in: a shipped one or a JSON file. A real robot
    /// starts dead reckoning at its start pose.
    #[arg(long, default_value = "navigation")]
    arena: String,
    /// Address to listen on; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:7400")]
    listen: SocketAddr,
    /// Operators must present this token in their hello.
    #[arg(long)]
    token: Option<String>,
    /// Seed for the simulator's noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(clap::Args)]
struct GuestArgs {
    /// The Host's WebSocket URL.
    #[arg(long, default_value = "ws://127.0.0.1:7400")]
    connect: String,
    /// Watch only; another person drives.
    #[arg(long)]
    observer: bool,
    /// The operator token the Host asks for.
    #[arg(long)]
    token: Option<String>,
    /// No window: drive the robot to the experiment's goal and report.
    #[arg(long)]
    headless: bool,
    /// With --headless: print the report as JSON.
    #[arg(long, requires = "headless")]
    json: bool,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Args)]
struct DemoArgs {
    /// No window: a scripted Guest drives the robot to the goal and reports.
    #[arg(long)]
    headless: bool,
    /// Print the headless report as JSON.
    #[arg(long)]
    json: bool,
    /// Seed for the simulator's noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Args)]
struct RunArgs {
    /// Experiment to mount for a headless run.
    #[arg(long, default_value = "navigation")]
    experiment: String,
    /// Give up a headless run after this many seconds.
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
}

fn main() -> ExitCode {
    // Like any Unix filter, end quietly when a reader such as `head` closes
    // the pipe, rather than panicking inside println!.
    // SAFETY: restoring the default action of one signal before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("vl: {e:#}");
            if e.downcast_ref::<BadInput>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    let runtime = || tokio::runtime::Runtime::new().context("cannot start the async runtime");
    match cli.command {
        Command::Host(args) => runtime()?.block_on(host(args)).map(|()| ExitCode::SUCCESS),
        Command::Guest(args) => guest(&runtime()?, args),
        Command::Demo(args) => demo(&runtime()?, args),
        Command::Petri(command) => petri::run(command),
        Command::KheperaEmu(args) => khepera_emu(args),
        Command::Sim(command) => sim::run(command),
        Command::Vision(command) => vision::run(command),
        Command::Plan(args) => plan::run(args),
    }
}

fn khepera_emu(args: KheperaArgs) -> Result<ExitCode> {
    let model = args.robot.model()?;
    let name = model.name.clone();
    let world = vl_sim::World::new(sim::arena_named(&args.arena)?, model, args.seed)
        .map_err(|e| BadInput(e.to_string()))?;
    let line = vl_sim::Line {
        baud: args.baud,
        timing: args.line_timing,
    };
    let mut emulator =
        vl_sim::Emulator::open(vl_sim::Khepera::new(world), line, args.link.as_deref())?;
    // Scripts and tests read the device from this first line.
    println!("vl khepera-emu: {name} on {}", emulator.device());
    use std::io::Write as _;
    std::io::stdout().flush()?;
    emulator.run()?;
    Ok(ExitCode::SUCCESS)
}

async fn host(args: HostArgs) -> Result<()> {
    let config = HostConfig {
        token: args.token,
        ..HostConfig::default()
    };
    let arena = sim::arena_named(&args.arena)?;
    let host = match (args.robot, args.camera) {
        (RobotKind::Sim, camera) => {
            let with_camera = camera == CameraKind::Sim;
            Host::start_sim(args.listen, arena, args.seed, with_camera, config).await
        }
        (RobotKind::Khepera, CameraKind::Sim) => {
            return Err(BadInput(
                "the simulated camera watches only the simulated robot; use --camera none".into(),
            )
            .into());
        }
        (RobotKind::Khepera, CameraKind::None) => {
            let port = args.port.as_deref().expect("clap requires --port");
            let robot = KheperaSerial::open(port, args.baud, RobotModel::khepera_ii(), arena.start)
                .context("no Khepera to drive")?;
            Host::start(args.listen, Box::new(robot), None, arena, config).await
        }
    }
    .context("cannot start the Host")?;
    // Scripts and tests read the bound address from this first line.
    println!("vl host listening on {}", host.url());
    tokio::select! {
        () = host.wait() => bail!("the server stopped"),
        signal = tokio::signal::ctrl_c() => {
            signal.context("cannot wait for Ctrl-C")?;
            eprintln!("vl host: stopping");
            Ok(())
        }
    }
}

fn guest(runtime: &tokio::runtime::Runtime, args: GuestArgs) -> Result<ExitCode> {
    if args.headless {
        let script = script(&args.run, args.token, !args.json);
        let report = runtime.block_on(drive_to_goal(&args.connect, &script))?;
        return Ok(print_report(&report, args.json));
    }
    let role = if args.observer {
        Role::Observer
    } else {
        Role::Operator
    };
    let connection = runtime.block_on(vl_guest::client::connect(&args.connect))?;
    let _entered = runtime.enter();
    vl_guest::app::run_window(connection, role, args.token)
        .map_err(|e| anyhow::anyhow!("the Guest window failed: {e}"))?;
    Ok(ExitCode::SUCCESS)
}

fn demo(runtime: &tokio::runtime::Runtime, args: DemoArgs) -> Result<ExitCode> {
    let listen: SocketAddr = "127.0.0.1:0".parse().expect("a valid address");
    let host = runtime
        .block_on(Host::start_sim(
            listen,
            Arena::navigation(),
            args.seed,
            true,
            HostConfig::default(),
        ))
        .context("cannot start the simulated Host")?;
    let has_display =
        std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some();
    if !args.headless && !has_display {
        eprintln!(
            "vl demo: no display (neither DISPLAY nor WAYLAND_DISPLAY is set); running headless"
        );
    }
    if args.headless || !has_display {
        let script = script(&args.run, None, !args.json);
        let report = runtime.block_on(drive_to_goal(&host.url(), &script))?;
        return Ok(print_report(&report, args.json));
    }
    eprintln!("vl demo: simulated lab at {}", host.url());
    let connection = runtime.block_on(vl_guest::client::connect(&host.url()))?;
    let _entered = runtime.enter();
    vl_guest::app::run_window(connection, Role::Operator, None)
        .map_err(|e| anyhow::anyhow!("the Guest window failed: {e}"))?;
    Ok(ExitCode::SUCCESS)
}

fn script(run: &RunArgs, token: Option<String>, progress: bool) -> Script {
    Script {
        experiment: run.experiment.clone(),
        token,
        timeout: Duration::from_secs_f64(run.timeout.max(0.0)),
        progress,
        ..Script::default()
    }
}

/// Prints the run's report; success means the robot reached its goal.
fn print_report(report: &Report, json: bool) -> ExitCode {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(report).expect("reports serialise")
        );
    } else {
        let rows = [
            ("reached goal", report.reached_goal.to_string()),
            ("end", format!("{:?}", report.reason)),
            ("events", report.events.to_string()),
            (
                "final pose",
                format!(
                    "({:.1}, {:.1}) mm, {:.1}°",
                    report.final_pose.x_mm,
                    report.final_pose.y_mm,
                    report.final_pose.theta_rad.to_degrees()
                ),
            ),
            ("lab time", format!("{:.2} s", report.sim_seconds)),
            ("distance", format!("{:.0} mm", report.distance_mm)),
            ("collisions", report.collisions.to_string()),
            ("frames", report.frames.to_string()),
            (
                "round trip",
                format!(
                    "p50 {:.2} ms, p99 {:.2} ms",
                    report.round_trip_ms.p50, report.round_trip_ms.p99
                ),
            ),
        ];
        for (name, value) in rows {
            println!("{name:>12}  {value}");
        }
    }
    if report.reached_goal {
        ExitCode::SUCCESS
    } else {
        eprintln!("vl: the robot did not reach the goal ({:?})", report.reason);
        ExitCode::FAILURE
    }
}
