//! The lab's own commands: `vl host` serves it, `vl guest` uses it,
//! `vl demo` runs both on the simulated lab, `vl khepera-emu` stands in for
//! the robot.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use vl_core::{Arena, Experiment, RobotKind, RobotModel, Role};
use vl_guest::{
    ClientError, Report as RunReport, RoundTripMs, Script, ScriptError, Watched, WindowError,
};
use vl_host::{Devices, Host, HostConfig, KheperaSerial, Media, SimCamera, SimLab};

use crate::input::{
    CameraDriver, FramesArgs, OpticsArgs, RobotArgs, SceneArgs, load_calibration, load_robot_model,
    parse_camera, real_camera, seconds,
};
use crate::media::LinkArgs;
use crate::report::{Report, Table, count, emit};
use crate::{BadInput, named};

#[derive(clap::Args)]
pub(crate) struct KheperaArgs {
    /// The arena the simulated robot drives in: a shipped one or a JSON file.
    #[arg(long, default_value = "navigation")]
    arena: String,
    #[command(flatten)]
    robot: RobotArgs,
    /// The line speed to emulate: each command and reply takes the time
    /// its characters take at this baud, as on a real serial cable.
    #[arg(long, default_value_t = 38_400)]
    baud: u32,
    /// Also make a symlink to the device here.
    #[arg(long)]
    link: Option<std::path::PathBuf>,
    /// Answer at once, whatever --baud says (a line no real robot has).
    #[arg(long)]
    instant_line: bool,
    /// Print each command line received, with the milliseconds since start.
    #[arg(long)]
    log_commands: bool,
    /// Print the robot's true pose and its contacts so far 20 times a
    /// second (`truth T X Y θ CONTACTS`): what tests judge a run by, and
    /// render a camera's frames from.
    #[arg(long)]
    truth: bool,
    /// Where the robot is put, x,y[,θ] mm and rad (default: the arena's
    /// start); give `vl host` the same to dead-reckon from it.
    #[arg(long, allow_hyphen_values = true)]
    start: Option<vl_core::Pose>,
    /// Seed for the sensors' noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// `vl serial-guard`: holds a robot's serial line for `vl host` and stops
/// the robot when the Host's end closes.
#[derive(clap::Args)]
pub(crate) struct GuardArgs {
    #[arg(long)]
    port: String,
    #[arg(long, default_value_t = 38_400)]
    baud: u32,
}

pub(crate) fn serial_guard(args: GuardArgs) -> Result<ExitCode> {
    // A Host that dies mid-exchange leaves the reply nowhere to go: the
    // guard must see that as an error and stop the robot, not be killed
    // by SIGPIPE as a filter would be.
    // SAFETY: setting one signal's action before the guard starts any thread.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
    // The Host heard of any failure through the pipe already.
    Ok(match vl_host::run_guard(&args.port, args.baud) {
        Ok(()) => ExitCode::SUCCESS,
        Err(_) => ExitCode::FAILURE,
    })
}

/// `vl khepera …`: tools for a real Khepera on its serial line.
#[derive(clap::Subcommand)]
pub(crate) enum KheperaTool {
    /// Measure the speed controller's step response through the serial
    /// driver (thesis C.2) and write a robot model file for `vl host`,
    /// `vl sim` and `vl khepera-emu` (--robot-model). The robot drives back
    /// and forth up to about 100 mm along its heading: give it room.
    Characterise(CharacteriseArgs),
}

#[derive(clap::Args)]
pub(crate) struct CharacteriseArgs {
    /// The robot's serial device.
    #[arg(long)]
    port: String,
    #[arg(long, default_value_t = 38_400)]
    baud: u32,
    /// Which Khepera it is (its size and sensors).
    #[arg(long, value_parser = named::<RobotKind>(), default_value = "khepera-ii")]
    robot: RobotKind,
    /// Where to write the robot model with the fitted response.
    #[arg(short, long, default_value = "khepera-model.json")]
    output: std::path::PathBuf,
    #[arg(long)]
    json: bool,
}

/// What `vl khepera characterise` found.
#[derive(serde::Serialize)]
struct Characterised {
    fit: vl_core::Fit,
    model_file: std::path::PathBuf,
}

impl Report for Characterised {
    fn table(&self) -> Table {
        let r = self.fit.response;
        Table::pairs([
            ("gain", format!("{:.3}", r.gain)),
            (
                "time constant",
                format!("{:.1} ms", r.time_constant_s * 1e3),
            ),
            ("acceleration", format!("{:.0} mm/s²", r.max_accel_mm_s2)),
            ("dead time", format!("{:.1} ms", r.dead_time_s * 1e3)),
            (
                "fit",
                format!(
                    "{:.1} mm/s RMS over {}",
                    self.fit.rms_mm_s,
                    count(self.fit.samples as u64, "sample", "samples")
                ),
            ),
            ("model", format!("wrote {}", self.model_file.display())),
        ])
    }
}

pub(crate) fn khepera(tool: KheperaTool) -> Result<ExitCode> {
    let KheperaTool::Characterise(args) = tool;
    let mut model = args.robot.model();
    let mut robot = KheperaSerial::open(
        &args.port,
        args.baud,
        model.clone(),
        vl_core::Pose::default(),
    )
    .context("no Khepera to characterise")?;
    let quiet = args.json;
    let fit = vl_host::characterise(&mut robot, &mut |step: &str| {
        if !quiet {
            eprintln!("{step} …");
        }
    })?;
    model.response = fit.response;
    model.name = format!("{} (characterised)", model.name);
    let text = serde_json::to_string_pretty(&model)?;
    std::fs::write(&args.output, text + "\n")
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    emit(
        &Characterised {
            fit,
            model_file: args.output,
        },
        args.json,
    )?;
    Ok(ExitCode::SUCCESS)
}

#[derive(Clone, Copy, PartialEq, clap::ValueEnum)]
enum RobotDriver {
    /// The simulated Khepera II.
    Sim,
    /// A Khepera I/II on the serial line --port.
    Khepera,
}

/// `vl host`: serve the lab, or measure how it answers.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub(crate) struct HostCommand {
    #[command(subcommand)]
    tool: Option<HostTool>,
    #[command(flatten)]
    serve: HostArgs,
}

#[derive(clap::Subcommand)]
enum HostTool {
    /// Time an operator's command to the feedback of its event on a
    /// simulated Host (camera streaming) while observers read everything.
    Bench {
        /// Observers connected and reading.
        #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(0..=1000))]
        observers: u64,
        /// Commands timed, each sent when the last one's feedback arrived.
        #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        commands: u64,
        #[arg(long)]
        json: bool,
    },
}

impl Report for vl_host::OperatorLatency {
    fn table(&self) -> Table {
        Table::pairs([
            ("observers reading", self.observers.to_string()),
            ("commands timed", self.commands.to_string()),
            ("p50", format!("{:.2} ms", self.p50_ms)),
            ("p90", format!("{:.2} ms", self.p90_ms)),
            ("p99", format!("{:.2} ms", self.p99_ms)),
            ("max", format!("{:.2} ms", self.max_ms)),
            (
                "feedback to the slowest observer",
                format!("{:.1} /s", self.observer_feedback_hz),
            ),
            (
                "frames to the slowest observer",
                format!("{:.1} /s", self.observer_frames_hz),
            ),
        ])
        .title("an operator's command to the feedback of its event, on loopback:")
    }
}

pub(crate) async fn host_command(command: HostCommand) -> Result<()> {
    match command.tool {
        Some(HostTool::Bench {
            observers,
            commands,
            json,
        }) => {
            let latency = vl_host::operator_latency(observers as usize, commands as usize)
                .await
                .context("the operator bench failed")?;
            emit(&latency, json)
        }
        None => host(command.serve).await,
    }
}

#[derive(clap::Args)]
pub(crate) struct HostArgs {
    /// Which robot to drive.
    #[arg(long, value_enum, default_value = "sim")]
    robot: RobotDriver,
    /// The serial device of a Khepera (with --robot khepera).
    #[arg(long, required_if_eq("robot", "khepera"))]
    port: Option<String>,
    /// The serial line's speed (with --robot khepera).
    #[arg(long, default_value_t = 38_400)]
    baud: u32,
    /// Which camera to watch the arena with: sim, none, http://… (a network
    /// camera's MJPEG stream), v4l2:/dev/videoN[,640x480][,15fps][,mjpeg|yuyv]
    /// (a webcam), or dir:PATH to play recorded footage back (its images in
    /// name order, 15 a second); a real robot has no simulated camera, so
    /// the default there is none.
    #[arg(
        long,
        value_parser = parse_camera,
        default_value_if("robot", "khepera", "none"),
        default_value = "sim"
    )]
    camera: CameraDriver,
    /// The arena the robot is in: a shipped one or a JSON file. A real robot
    /// starts dead reckoning at its start pose.
    #[arg(long, default_value = "navigation")]
    arena: String,
    /// The experiments to offer, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = named::<Experiment>(),
        default_value = "navigation,teleoperation"
    )]
    experiments: Vec<Experiment>,
    /// Address to listen on; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:7400", value_parser = crate::listen_address)]
    listen: SocketAddr,
    /// Operators must present this token in their hello.
    #[arg(long)]
    token: Option<String>,
    /// An operator who sends no command for this many seconds during a run
    /// loses the run and the role.
    #[arg(long, default_value_t = 30.0)]
    lease: f64,
    /// A client the Host hears nothing from for this many seconds (no
    /// answer to its pings) is disconnected.
    #[arg(long, default_value_t = 10.0)]
    ping_timeout: f64,
    /// An operator whose link drops keeps the role and the run this many
    /// seconds (the robot held still) to reconnect; 0 frees them at once.
    #[arg(long, default_value_t = 10.0)]
    grace: f64,
    /// Leave the robot where a run ends, instead of driving it back to the
    /// lab's start pose (where nothing may move unattended).
    #[arg(long)]
    no_reset: bool,
    /// Fold camera sightings in when they arrive, not when their frames
    /// were taken: to see what latency compensation is worth.
    #[arg(long)]
    no_latency_compensation: bool,
    /// Run the labs' controlled nets from this folder (as `vl lab nets
    /// --out DIR` writes them) instead of the built-in ones.
    #[arg(long)]
    nets: Option<PathBuf>,
    /// Seed for the simulator's noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Where the robot starts, x,y[,θ] mm and rad: the simulated robot is
    /// put there, a real one starts dead reckoning there (default: the
    /// arena's start).
    #[arg(long, allow_hyphen_values = true)]
    start: Option<vl_core::Pose>,
    /// The robot's model from a JSON file (`vl khepera characterise`
    /// writes one; default: the Khepera II's).
    #[arg(long)]
    robot_model: Option<std::path::PathBuf>,
    /// The camera's calibration (`vl camera calibrate -o` writes one).
    /// Without it a simulated camera is calibrated from a dot target when
    /// the Host starts.
    #[arg(long)]
    camera_calibration: Option<std::path::PathBuf>,
    #[command(flatten)]
    optics: OpticsArgs,
    #[command(flatten)]
    frames: FramesArgs,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    link: LinkArgs,
}

#[derive(clap::Args)]
pub(crate) struct GuestArgs {
    /// The Host's WebSocket URL.
    #[arg(long, default_value = "ws://127.0.0.1:7400")]
    connect: String,
    /// Watch only; another person drives.
    #[arg(long)]
    observer: bool,
    /// The operator token the Host asks for.
    #[arg(long)]
    token: Option<String>,
    /// No window: drive the robot to the experiment's goal and report; as
    /// an observer, watch until a run ends (or --timeout) and report.
    #[arg(long)]
    headless: bool,
    /// With --headless: print the report as JSON.
    #[arg(long, requires = "headless")]
    json: bool,
    /// A real gamepad or joystick to drive with and feel the force on:
    /// auto (the first one found), none, or its /dev/input/eventN device.
    #[arg(long, default_value = "auto")]
    gamepad: GamepadChoice,
    /// Count the gamepad's stick only while its dead-man button (left
    /// shoulder or trigger) is held.
    #[arg(long)]
    dead_man: bool,
    #[command(flatten)]
    run: RunArgs,
}

/// Which gamepad the window reads.
#[derive(Clone, Debug)]
enum GamepadChoice {
    Auto,
    None,
    Device(std::path::PathBuf),
}

impl std::str::FromStr for GamepadChoice {
    type Err = std::convert::Infallible;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Ok(match text {
            "auto" => GamepadChoice::Auto,
            "none" => GamepadChoice::None,
            path => GamepadChoice::Device(path.into()),
        })
    }
}

/// The gamepad asked for: gamepads are read through Linux's evdev.
fn gamepad(choice: &GamepadChoice, dead_man: bool) -> Result<Option<Box<dyn vl_guest::Pad>>> {
    #[cfg(target_os = "linux")]
    {
        use vl_guest::Gamepad;
        let pad = match choice {
            GamepadChoice::None => None,
            GamepadChoice::Auto => Gamepad::find(dead_man),
            GamepadChoice::Device(path) => {
                Some(Gamepad::open(path, dead_man).map_err(|e| BadInput(e.to_string()))?)
            }
        };
        if let Some(pad) = &pad {
            let feel = if pad.has_force_feedback() {
                "with force feedback"
            } else {
                "without force feedback"
            };
            eprintln!(
                "vl guest: driving with {} ({feel})",
                vl_guest::Pad::name(pad)
            );
        }
        Ok(pad.map(|p| Box::new(p) as Box<dyn vl_guest::Pad>))
    }
    #[cfg(not(target_os = "linux"))]
    match choice {
        GamepadChoice::Device(_) => {
            Err(BadInput("gamepads are read through Linux's evdev only".into()).into())
        }
        _ => {
            let _ = dead_man;
            Ok(None)
        }
    }
}

#[derive(clap::Args)]
pub(crate) struct DemoArgs {
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
    link: LinkArgs,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Args)]
pub(crate) struct RunArgs {
    /// Experiment to mount for a headless run.
    #[arg(long, value_parser = named::<Experiment>(), default_value = "navigation")]
    experiment: Experiment,
    /// Give up a headless run (stop watching, as an observer) after this many seconds.
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    /// Where a headless run drives to, x,y mm (default: the arena's goal).
    #[arg(long, allow_hyphen_values = true)]
    goal: Option<vl_core::Point>,
}

pub(crate) fn khepera_emu(args: KheperaArgs) -> Result<ExitCode> {
    let model = args.robot.model()?;
    let name = model.name.clone();
    let arena = arena_from(&args.arena, args.start)?;
    let world = vl_sim::World::new(arena, model, args.seed).map_err(|e| BadInput(e.to_string()))?;
    let line = vl_sim::Line {
        baud: args.baud,
        timing: !args.instant_line,
        log_commands: args.log_commands,
        truth: args.truth,
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

/// The arena `name` (shipped, or a JSON file) with the robot put at
/// `start` when one is given: where the simulated robot stands, and where
/// a real one's dead reckoning begins.
fn arena_from(name: &str, start: Option<vl_core::Pose>) -> Result<Arena> {
    let mut arena = Arena::load(name).map_err(|e| BadInput(e.to_string()))?;
    if let Some(start) = start {
        arena.start = start;
        arena
            .check()
            .map_err(|e| BadInput(format!("--start: {e}")))?;
    }
    Ok(arena)
}

/// The Host's configuration from its flags, checked before anything starts.
fn host_config(args: &HostArgs) -> Result<HostConfig> {
    if args.experiments.is_empty() {
        bail!(BadInput("--experiments names none to offer".into()));
    }
    let config = HostConfig {
        token: args.token.clone(),
        experiments: args.experiments.clone(),
        lease: seconds("--lease", args.lease)?,
        ping_timeout: seconds("--ping-timeout", args.ping_timeout)?,
        grace: if args.grace == 0.0 {
            Duration::ZERO
        } else {
            seconds("--grace", args.grace)?
        },
        frames: args.frames.policy()?,
        nets: args.nets.clone(),
        reset: !args.no_reset,
        compensate_latency: !args.no_latency_compensation,
        ..HostConfig::default()
    };
    // A folder of nets that cannot run is the user's to fix, before anything starts.
    config
        .supervisor()
        .map_err(|e| BadInput(format!("--nets: {e}")))?;
    Ok(config)
}

pub(crate) async fn host(args: HostArgs) -> Result<()> {
    let config = host_config(&args)?;
    let arena = arena_from(&args.arena, args.start)?;
    let optics = args.optics.optics(args.seed)?;
    let model = match &args.robot_model {
        Some(file) => load_robot_model(file)?,
        None => RobotModel::khepera_ii(),
    };
    let calibration = match &args.camera_calibration {
        Some(path) => Some(load_calibration(path)?),
        None => None,
    };
    // Behind a modelled link the Host listens privately and the Media on --listen.
    let linked = args.link.model()?.is_some();
    let public = args.listen;
    let listen: SocketAddr = if linked {
        ([127, 0, 0, 1], 0).into()
    } else {
        public
    };
    let host = match (args.robot, args.camera) {
        (RobotDriver::Sim, CameraDriver::Replay(_)) => {
            return Err(BadInput(
                "recorded footage shows a recorded robot, not the simulated one: replay it with --robot khepera".into(),
            )
            .into());
        }
        (RobotDriver::Sim, camera @ (CameraDriver::Sim | CameraDriver::None)) => {
            let lab = SimLab {
                arena,
                robot: model,
                seed: args.seed,
                camera: (camera == CameraDriver::Sim).then_some(SimCamera {
                    optics,
                    calibration,
                }),
                scene: args.scene.events,
            };
            Host::start_sim(listen, lab, config).await
        }
        (RobotDriver::Sim, _) => {
            return Err(BadInput(
                "a real camera watches a real robot, not the simulated one: use --robot khepera".into(),
            )
            .into());
        }
        (RobotDriver::Khepera, CameraDriver::Sim) => {
            return Err(BadInput(
                "the simulated camera watches only the simulated robot; use --camera none".into(),
            )
            .into());
        }
        (RobotDriver::Khepera, camera) => {
            let Some(port) = args.port.as_deref() else {
                bail!(BadInput("--robot khepera needs --port DEVICE".into()));
            };
            let camera = real_camera(camera, calibration, &arena).context(
                "no camera to watch the arena with (given --camera-calibration, the Host does not wait for its first frame)",
            )?;
            // A guard process holds the line and stops the robot if this one dies.
            let program = std::env::current_exe().context("cannot find the vl binary")?;
            let robot = KheperaSerial::guarded(program, port, args.baud, model, arena.start)
                .context("no Khepera to drive")?;
            let devices = Devices {
                robot: Box::new(robot),
                camera,
                witness: None,
            };
            Host::start(listen, devices, arena, config).await
        }
    }
    .context("cannot start the Host")?;
    let media = args.link.front(public, &host.url()).await?;
    // Scripts and tests read the bound address from this first line.
    match &media {
        Some(media) => println!(
            "vl host listening on {} (through a modelled link to {})",
            media.url(),
            host.url()
        ),
        None => println!("vl host listening on {}", host.url()),
    }
    let relaying = async {
        match media {
            Some(media) => media.wait().await,
            None => std::future::pending().await,
        }
    };
    tokio::select! {
        () = host.wait() => bail!("the server stopped"),
        () = relaying => bail!("the Media stopped"),
        signal = tokio::signal::ctrl_c() => {
            signal.context("cannot wait for Ctrl-C")?;
            eprintln!("vl host: stopping");
            Ok(())
        }
    }
}

/// A Guest error: an address that cannot be a Host's is the user's input.
fn guest_error(e: impl Into<anyhow::Error>) -> anyhow::Error {
    let e = e.into();
    let bad_url = |c: &ClientError| matches!(c, ClientError::BadUrl { .. });
    let is_bad_url = match e.downcast_ref::<ScriptError>() {
        Some(ScriptError::Connect(c)) => bad_url(c),
        _ => match e.downcast_ref::<WindowError>() {
            Some(WindowError::Address(c)) => bad_url(c),
            _ => false,
        },
    };
    if is_bad_url {
        BadInput(e.to_string()).into()
    } else {
        e
    }
}

pub(crate) fn guest(runtime: &tokio::runtime::Runtime, args: GuestArgs) -> Result<ExitCode> {
    let role = if args.observer {
        Role::Observer
    } else {
        Role::Operator
    };
    if args.headless {
        let script = script(&args.run, args.token, !args.json);
        if role == Role::Observer {
            let watched = interruptible(runtime, vl_guest::watch(&args.connect, &script))?
                .map_err(guest_error)?;
            emit(&watched, args.json)?;
            return Ok(ExitCode::SUCCESS);
        }
        let report = interruptible(runtime, vl_guest::run_script(&args.connect, &script))?
            .map_err(guest_error)?;
        return finish(&report, args.json);
    }
    let pad = gamepad(&args.gamepad, args.dead_man)?;
    let _entered = runtime.enter();
    let shown = vl_guest::run_window(&args.connect, role, args.token, pad);
    // The window is gone and with it its connection: give the goodbye
    // time to leave, so an operator's role is free at once.
    std::thread::sleep(GOODBYE_WAIT);
    shown.map_err(guest_error)?;
    Ok(ExitCode::SUCCESS)
}

/// How long a Guest that ends lets its connection's goodbye go out.
const GOODBYE_WAIT: Duration = Duration::from_millis(300);

/// Runs a headless Guest until it ends or Ctrl-C; on Ctrl-C its connection
/// is dropped, which closes the WebSocket (a goodbye: the Host frees the
/// operator's role at once), and the Guest exits with 130.
fn interruptible<T>(
    runtime: &tokio::runtime::Runtime,
    guest: impl std::future::Future<Output = T>,
) -> Result<T> {
    runtime.block_on(async {
        tokio::select! {
            done = guest => Ok(done),
            _ = tokio::signal::ctrl_c() => {
                tokio::time::sleep(GOODBYE_WAIT).await;
                eprintln!("vl guest: interrupted; said goodbye to the Host");
                std::process::exit(130);
            }
        }
    })
}

pub(crate) fn demo(runtime: &tokio::runtime::Runtime, args: DemoArgs) -> Result<ExitCode> {
    let listen: SocketAddr = ([127, 0, 0, 1], 0).into();
    let host = runtime
        .block_on(Host::start_sim(
            listen,
            SimLab {
                seed: args.seed,
                ..SimLab::new(Arena::navigation())
            },
            HostConfig::default(),
        ))
        .context("cannot start the simulated Host")?;
    let media = runtime.block_on(args.link.front(listen, &host.url()))?;
    let url = media.as_ref().map_or_else(|| host.url(), Media::url);
    let has_display =
        std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some();
    if !args.headless && !has_display {
        eprintln!(
            "vl demo: no display (neither DISPLAY nor WAYLAND_DISPLAY is set); running headless"
        );
    }
    if args.headless || !has_display {
        let script = script(&args.run, None, !args.json);
        let report = interruptible(runtime, vl_guest::run_script(&url, &script))??;
        return finish(&report, args.json);
    }
    eprintln!("vl demo: simulated lab at {url}");
    let _entered = runtime.enter();
    let pad = gamepad(&GamepadChoice::Auto, false)?;
    vl_guest::run_window(&url, Role::Operator, None, pad)?;
    Ok(ExitCode::SUCCESS)
}

fn script(run: &RunArgs, token: Option<String>, progress: bool) -> Script {
    Script {
        experiment: run.experiment,
        goal: run.goal.map(vl_core::Goal::at),
        token,
        timeout: Duration::from_secs_f64(run.timeout.clamp(0.0, 1e6)),
        progress,
        ..Script::default()
    }
}

/// Prints the run's report; success means the robot reached its goal.
fn finish(report: &RunReport, json: bool) -> Result<ExitCode> {
    emit(report, json)?;
    if report.reached_goal {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("vl: the robot did not reach the goal ({})", report.ending());
        Ok(ExitCode::FAILURE)
    }
}

fn round_trip(rtt: &RoundTripMs) -> String {
    format!("p50 {:.2} ms, p99 {:.2} ms", rtt.p50, rtt.p99)
}

impl Report for RunReport {
    fn table(&self) -> Table {
        let pose = self.final_pose;
        Table::pairs([
            (
                "reached goal",
                crate::report::yes(self.reached_goal).to_owned(),
            ),
            ("end", self.ending()),
            ("events", self.events.to_string()),
            (
                "final pose",
                format!(
                    "({:.1}, {:.1}) mm, {:.1}°",
                    pose.x_mm,
                    pose.y_mm,
                    pose.theta_rad.to_degrees()
                ),
            ),
            ("lab time", format!("{:.2} s", self.sim_seconds)),
            ("distance", format!("{:.0} mm", self.distance_mm)),
            ("collisions", self.collisions.to_string()),
            ("pose from", self.pose_source.to_string()),
            (
                "path error",
                error_mm(self.path.as_ref().and_then(|p| p.path_error_mm)),
            ),
            (
                "estimate error",
                error_mm(self.path.as_ref().and_then(|p| p.estimate_error_mm)),
            ),
            (
                "frames",
                format!("{} ({:.0} kB)", self.frames, self.video_bytes as f64 / 1e3),
            ),
            ("round trip", round_trip(&self.round_trip_ms)),
        ])
    }
}

/// Error statistics in a table cell; a dash when nothing was measured.
pub(crate) fn error_mm(e: Option<vl_core::ErrorMm>) -> String {
    e.map_or("–".into(), |e| {
        format!(
            "mean {:.1} mm, max {:.1} mm, rms {:.1} mm",
            e.mean, e.max, e.rms
        )
    })
}

impl Report for Watched {
    fn table(&self) -> Table {
        let run = match &self.run {
            Some(done) => format!(
                "{} after {:.1} s, {}",
                done.ending(),
                done.seconds,
                count(done.events, "event", "events")
            ),
            None => "none ended while watching".into(),
        };
        Table::pairs([
            (
                "mounted",
                self.experiment
                    .map_or("nothing".to_owned(), |e| e.title().to_owned()),
            ),
            ("run", run),
            ("feedback", self.feedback.to_string()),
            ("frames", self.frames.to_string()),
            ("round trip", round_trip(&self.round_trip_ms)),
        ])
    }
}
