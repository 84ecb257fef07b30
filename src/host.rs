//! `vl host`: serve the lab on a simulated or real robot and camera, or
//! measure how it answers (`vl host bench`).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::ValueHint;
use vl_core::RobotModel;
use vl_host::{CameraSource, Host, HostConfig, LabSpec, RobotSpec};

use crate::access::AccessArgs;
use crate::input::{SceneArgs, arena_from, load_calibration, load_robot_model};
use crate::media::LinkArgs;
use crate::named::{ExperimentChoice, ExperimentChoiceParser, offered};
use crate::report::emit;
use crate::{BadInput, bad_input, named};

pub(crate) mod plugs;

/// Which robot `vl host` drives.
#[derive(Clone, Copy, PartialEq)]
enum RobotDriver {
    /// The simulated Khepera II.
    Sim,
    /// A Khepera I/II on the serial line --port.
    Khepera,
    /// A ROS 2 differential-drive robot on the Zenoh network (--zenoh):
    /// Twists on /cmd_vel, its /odom read.
    Ros2,
}

impl vl_core::Named for RobotDriver {
    const KIND: &'static str = "robot";
    const ALL: &'static [RobotDriver] =
        &[RobotDriver::Sim, RobotDriver::Khepera, RobotDriver::Ros2];

    fn id(self) -> &'static str {
        match self {
            RobotDriver::Sim => "sim",
            RobotDriver::Khepera => "khepera",
            RobotDriver::Ros2 => "ros2",
        }
    }
}

/// Which camera `--camera` names: one the lab opens, or a ROS 2 robot's
/// own (`ros2:/TOPIC`, read on the robot's network).
#[derive(Clone)]
enum CameraArg {
    Source(CameraSource),
    Ros2(String),
}

fn camera_arg(text: &str) -> Result<CameraArg> {
    match text.strip_prefix("ros2:") {
        Some(topic) => plugs::ros2_camera(topic).map(CameraArg::Ros2),
        None => Ok(CameraArg::Source(text.parse().map_err(bad_input)?)),
    }
}

/// `vl host`: serve the lab, or measure how it answers.
/// `vl host bench-watchers`'s flags.
#[derive(clap::Args)]
pub(crate) struct WatchersArgs {
    /// Clients watching in the watched rounds.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..=240))]
    watchers: u64,
    /// Commands timed in each round.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    commands: u64,
    /// Rounds of each kind, alternating.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=100))]
    rounds: u64,
    /// The watchers are Foxglove clients subscribed to every channel.
    #[arg(long)]
    foxglove: bool,
    #[arg(long)]
    json: bool,
}

impl WatchersArgs {
    fn bench(&self) -> vl_host::WatchersBench {
        vl_host::WatchersBench {
            watchers: self.watchers,
            commands: self.commands,
            rounds: self.rounds,
            foxglove: self.foxglove,
        }
    }
}

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, args_override_self = true)]
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
    /// What a class watching costs the Host: its operator's command →
    /// feedback and its processor, with and without watchers.
    BenchWatchers(WatchersArgs),
    /// Ask a running Host how it is: devices, operator, line, runs today
    /// (an administrator's login at a lab with accounts).
    Status {
        /// The Host's address, as a Guest gives it.
        #[arg(default_value = "ws://127.0.0.1:7400")]
        url: String,
        #[command(flatten)]
        login: crate::login::LoginArgs,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) async fn host_command(command: HostCommand) -> Result<()> {
    match command.tool {
        Some(HostTool::Bench {
            observers,
            commands,
            json,
        }) => {
            let began = std::time::Instant::now();
            let step = |what: &str| {
                eprintln!(
                    "vl host bench: {:>4.0} s  {what}…",
                    began.elapsed().as_secs_f64()
                );
            };
            let extensions = plugs::always();
            let latency =
                vl_host::operator_latency(observers as usize, commands as usize, extensions, step)
                    .await
                    .context("the operator bench failed")?;
            emit(&latency, json)
        }
        Some(HostTool::BenchWatchers(bench)) => {
            let vl = std::env::current_exe().context("cannot find the vl binary")?;
            let cost = (bench.bench().run(&vl).await).context("the watchers bench failed")?;
            emit(&cost, bench.json)
        }
        Some(HostTool::Status { url, login, json }) => {
            emit(&vl_client::host_status(&url, &login.login()?).await?, json)
        }
        None => host(command.serve).await,
    }
}

#[derive(clap::Args)]
pub(crate) struct HostArgs {
    /// A lab file (TOML) of these options by name, e.g. `slot = "10m"`,
    /// `users = "users.toml"` (paths from the file's folder); options
    /// given here as well win.
    #[arg(long, value_hint = ValueHint::FilePath)]
    config: Option<PathBuf>,
    /// Which robot to drive: sim (the simulated Khepera II), khepera (a
    /// Khepera I/II on the serial line --port) or ros2 (a ROS 2 base on the
    /// Zenoh network: /cmd_vel out, /odom in).
    #[arg(long, value_parser = named::<RobotDriver>(), default_value = "sim")]
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
        value_parser = camera_arg,
        default_value_if("robot", "khepera", "none"),
        default_value_if("robot", "ros2", "none"),
        default_value = "sim"
    )]
    camera: CameraArg,
    /// The arena the robot is in: a shipped one or a JSON file. A real robot
    /// starts dead reckoning at its start pose.
    #[arg(long, default_value = "navigation", value_hint = ValueHint::AnyPath)]
    arena: String,
    /// The experiments to offer, comma-separated: ids, and experiment
    /// folders (or folders of them) to serve beside the shipped ones. With
    /// ids named, exactly those are offered (a folder's by its id); each
    /// folder is designed and verified first. Every shipped one when not
    /// given.
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = ExperimentChoiceParser,
        value_hint = ValueHint::AnyPath
    )]
    experiments: Vec<ExperimentChoice>,
    /// Address for Guests, browsers (the web page) and Foxglove alike; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:7400", value_parser = vl_core::listen_address)]
    listen: SocketAddr,
    /// An operator who sends no command this long (seconds, or 90s, 10m)
    /// during a run loses the run and the role.
    #[arg(long, default_value = "30", value_parser = crate::duration)]
    lease: Duration,
    /// How long an operator drives while others wait in line (90s, 10m, 1h).
    #[arg(long, value_parser = crate::duration)]
    slot: Option<Duration>,
    /// A client the Host hears nothing from this long (no answer to its
    /// pings) is disconnected.
    #[arg(long, default_value = "10", value_parser = crate::duration)]
    ping_timeout: Duration,
    /// An operator whose link drops keeps the role and the run this long
    /// (the robot held still) to reconnect; 0 frees them at once.
    #[arg(long, default_value = "10", value_parser = crate::duration_or_none)]
    grace: Duration,
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
    #[arg(long, value_hint = ValueHint::DirPath)]
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
    #[arg(long, value_hint = ValueHint::FilePath)]
    robot_model: Option<std::path::PathBuf>,
    /// The camera's calibration (`vl camera calibrate -o` writes one).
    /// Without it a simulated camera is calibrated from a dot target when
    /// the Host starts.
    #[arg(long, value_hint = ValueHint::FilePath)]
    camera_calibration: Option<std::path::PathBuf>,
    #[command(flatten)]
    optics: crate::options::OpticsArgs,
    #[command(flatten)]
    frames: crate::options::FrameArgs,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    link: LinkArgs,
    #[command(flatten)]
    access: AccessArgs,
    #[command(flatten)]
    forecast: crate::options::ForecastArgs,
    #[command(flatten)]
    recordings: crate::record::KeepArgs,
    /// Join the gateway whose Zenoh router is here (quic/HOST:PORT) as one
    /// of its cells (with --cell).
    #[arg(long, requires = "cell")]
    gateway: Vec<crate::options::ZenohEndpoint>,
    /// This cell's name at its gateway: 1–32 of a-z, 0-9, '-' and '_'.
    #[arg(long, requires = "gateway")]
    cell: Option<vl_core::CellName>,
    /// Publish the lab as ROS 2 topics (rmw_zenoh's wire format, no ROS
    /// installed): /odom, /tf, /scan, /map, the camera's.
    #[arg(long)]
    ros2: bool,
    /// The ROS 2 domain (ROS_DOMAIN_ID) of --ros2 and --robot ros2.
    #[arg(long, default_value = "0")]
    ros2_domain: u32,
    /// With --ros2: a Twist on /cmd_vel drives the robot in a teleoperation
    /// run, in its turn, as --ros2-as's account at a lab with accounts.
    #[arg(long, requires = "ros2")]
    ros2_operator: bool,
    /// The account /cmd_vel drives as, at a lab with accounts: anyone on
    /// the ROS 2 network drives as it (its turns, its line, the audit).
    #[arg(long, value_name = "ACCOUNT", requires = "ros2_operator")]
    ros2_as: Option<String>,
    /// The Zenoh network of --ros2 and --robot ros2.
    #[command(flatten)]
    zenoh: crate::options::ZenohArgs,
}

/// Where the Host records: a cell, unless told, in a folder of its own
/// (several cells may share one machine and its data directory).
fn recordings(args: &HostArgs) -> Result<Option<vl_record::Catalogue>> {
    let mut settings = args.recordings.settings();
    if let (Some(cell), None) = (&args.cell, &settings.recordings) {
        settings.recordings =
            vl_record::recordings_dir().map(|dir| dir.join("cells").join(cell.as_str()));
    }
    Ok(settings.catalogue().map_err(bad_input)?)
}

/// The Host's configuration from its flags, checked before anything starts.
fn host_config(args: &HostArgs) -> Result<HostConfig> {
    let mut config = HostConfig {
        experiments: offered(&args.experiments)?,
        lease: args.lease,
        slot: args.slot,
        ping_timeout: args.ping_timeout,
        grace: args.grace,
        frames: args.frames.policy(),
        nets: args.nets.clone(),
        reset: !args.no_reset,
        compensate_latency: !args.no_latency_compensation,
        forecast: args.forecast.settings(),
        recordings: recordings(args)?,
        ..HostConfig::default()
    };
    args.access.apply(&mut config)?;
    plugs::plug_in(args, &mut config)?;
    // A folder of nets that cannot run is the user's to fix, before anything starts.
    config
        .supervisor()
        .map_err(|e| BadInput(format!("--nets: {e}")))?;
    Ok(config)
}

/// The robot `--robot` names, with what driving it needs.
fn robot_spec(args: &HostArgs) -> Result<RobotSpec> {
    Ok(match args.robot {
        RobotDriver::Sim => RobotSpec::Sim,
        RobotDriver::Khepera => RobotSpec::Khepera {
            port: args
                .port
                .clone()
                .context("--robot khepera needs --port DEVICE")?,
            baud: args.baud,
            // A guard process holds the line and stops the robot if this one dies.
            guard: std::env::current_exe().context("cannot find the vl binary")?,
        },
        RobotDriver::Ros2 => plugs::ros2_robot(args)?,
    })
}

pub(crate) async fn host(args: HostArgs) -> Result<()> {
    let config = host_config(&args)?;
    if let Some(file) = &args.config {
        eprintln!("vl host: options from {}", file.display());
    }
    if let Some(kept) = &config.recordings {
        eprintln!("vl host: recording every run in {}", kept.dir().display());
    }
    let ids: Vec<String> = config
        .experiments
        .ids()
        .iter()
        .map(|id| id.to_string())
        .collect();
    eprintln!("vl host: offering {}", ids.join(", "));
    let robot = robot_spec(&args)?;
    plugs::camera_fits(&args, &robot)?;
    let spec = LabSpec {
        robot,
        camera: match &args.camera {
            CameraArg::Source(source) => source.clone(),
            // The robot brings it (`plugs::ros2_robot`).
            CameraArg::Ros2(_) => CameraSource::None,
        },
        arena: arena_from(&args.arena, args.start)?,
        model: match &args.robot_model {
            Some(file) => load_robot_model(file)?,
            None => RobotModel::khepera_ii(),
        },
        calibration: args
            .camera_calibration
            .as_deref()
            .map(load_calibration)
            .transpose()?,
        optics: args.optics.optics(args.seed).map_err(bad_input)?,
        seed: args.seed,
        scene: args.scene.events.clone(),
    };
    // Behind a modelled link the Host listens privately and the Media on --listen.
    let public = args.listen;
    let listen: SocketAddr = match args.link.model()? {
        Some(_) => ([127, 0, 0, 1], 0).into(),
        None => public,
    };
    let mut host = Host::serve(listen, spec, config).await.map_err(|e| {
        if e.is_bad_input() {
            BadInput(e.to_string()).into()
        } else {
            anyhow::Error::new(e)
        }
    })?;
    let media = args.link.front(public, &host.url()).await?;
    // Scripts and tests read the bound address from this first line.
    match &media {
        Some(media) => println!(
            "vl host listening on {} (through a modelled link to {})",
            media.url(),
            host.url()
        ),
        None => {
            println!("vl host listening on {}", host.url());
            let reachable = host.reachable_at();
            if reachable.len() == 1 || host.addr.ip().is_loopback() {
                eprintln!("vl host: a browser opens the lab at {}", host.page_url());
            } else {
                // Every interface: each address of this machine, as a
                // teacher hands one out.
                eprintln!(
                    "vl host: Guests on other machines connect to any of these \
                     (a firewall must let TCP port {} in):",
                    host.addr.port()
                );
                for (url, page) in reachable {
                    eprintln!("vl host:   {url}   (browser: {page})");
                }
            }
        }
    }
    eprintln!("vl host: {}", host.priority);
    let relaying = async {
        match media {
            Some(media) => media.wait().await,
            None => std::future::pending().await,
        }
    };
    let mut terminate = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .context("cannot wait for SIGTERM")?;
    tokio::select! {
        () = host.stopped() => bail!("the server stopped"),
        () = relaying => bail!("the Media stopped"),
        signal = tokio::signal::ctrl_c() => signal.context("cannot wait for Ctrl-C")?,
        _ = terminate.recv() => {}
    }
    eprintln!("vl host: stopping");
    host.stop().await;
    Ok(())
}
