//! `vl`: the virtual laboratory's one binary. `vl host` serves the lab,
//! `vl guest` is the user's desktop app, `vl demo` runs both on the
//! simulated lab; the tool subcommands reach the libraries' algorithms.
//! This crate only parses, dispatches and prints.

#[cfg(feature = "host")]
mod access;
#[cfg(feature = "host")]
mod camera;
mod controller;
#[cfg(feature = "host")]
mod experiment;
mod flag_file;
#[cfg(feature = "gateway")]
mod gateway;
#[cfg(feature = "guest")]
mod guest;
#[cfg(feature = "host")]
mod host;
mod input;
#[cfg(feature = "host")]
mod khepera;
mod login;
#[cfg(feature = "lti")]
mod lti;
#[cfg(feature = "host")]
mod media;
mod named;
mod nets;
mod options;
mod petri;
mod plan;
mod record;
mod regrade;
mod report;
mod shipped;
mod sim;
mod vision;

use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{CommandFactory, Parser, Subcommand};
use tracing_subscriber::EnvFilter;

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
    #[cfg(feature = "host")]
    Host(Box<host::HostCommand>),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    Host(Missing),
    /// The lab's one public address in front of many cells (each a `vl
    /// host --gateway … --cell NAME`), on Zenoh.
    #[cfg(feature = "gateway")]
    Gateway(gateway::GatewayCommand),
    /// Not in this vl: it was built without the `gateway` feature.
    #[cfg(not(feature = "gateway"))]
    Gateway(Missing),
    /// Open the Guest window on a Host (on the user's desktop).
    #[cfg(feature = "guest")]
    Guest(guest::GuestArgs),
    /// Not in this vl: it was built without the `guest` feature.
    #[cfg(not(feature = "guest"))]
    Guest(Missing),
    /// Run a Host on the simulated lab and a Guest against it, in one process.
    #[cfg(all(feature = "guest", feature = "host"))]
    Demo(guest::DemoArgs),
    /// Not in this vl: it was built without the `guest` and `host` features.
    #[cfg(not(all(feature = "guest", feature = "host")))]
    Demo(Missing),
    /// Relay Guests to a Host through a modelled Internet link (the Media).
    #[cfg(feature = "host")]
    Media(media::MediaCommand),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    Media(Missing),
    /// The labs' own nets, and experiment folders: statecharts to the
    /// controlled nets the Host runs, checked.
    #[command(subcommand)]
    Lab(nets::LabCommand),
    /// Analyse Petri nets (PNML).
    #[command(subcommand)]
    Petri(petri::PetriCommand),
    /// Emulate a Khepera II on a pseudo-terminal, backed by the simulator.
    #[cfg(feature = "host")]
    KheperaEmu(khepera::KheperaArgs),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    KheperaEmu(Missing),
    /// Tools for a real Khepera on its serial line.
    #[command(subcommand)]
    #[cfg(feature = "host")]
    Khepera(khepera::KheperaTool),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    Khepera(Missing),
    /// Holds a robot's serial line for `vl host` (started by it).
    #[command(hide = true)]
    #[cfg(feature = "host")]
    SerialGuard(khepera::GuardArgs),
    /// Not in this vl: it was built without the `host` feature.
    #[command(hide = true)]
    #[cfg(not(feature = "host"))]
    SerialGuard(Missing),
    /// The simulator's tools: scripted runs, camera frames, link models, speed.
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// Vision on camera frames: components, moments, the robot's pose.
    #[command(subcommand)]
    Vision(vision::VisionCommand),
    /// Plan a path on a top-view map: C-space, NF1, spline, clearance.
    Plan(plan::PlanArgs),
    /// A user's own wheel controller (WebAssembly): check it, try it on
    /// the lab's twin, time it.
    #[command(subcommand)]
    Controller(controller::ControllerCommand),
    /// Calibrate the overhead camera: its map from floor mm to pixels.
    #[command(subcommand)]
    #[cfg(feature = "host")]
    Camera(camera::CameraCommand),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    Camera(Missing),
    /// Keep a lab's accounts file: add, remove, passwd, list.
    #[command(subcommand)]
    #[cfg(feature = "host")]
    Users(access::UsersCommand),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    Users(Missing),
    /// The lab inside a teacher's LMS (LTI 1.3): platforms, the tool's configuration.
    #[command(subcommand)]
    #[cfg(feature = "lti")]
    Lti(lti::LtiCommand),
    /// Not in this vl: it was built without the `lti` feature.
    #[cfg(not(feature = "lti"))]
    Lti(Missing),
    /// Run the lab's experiments headless on the simulator and measure them.
    #[command(subcommand)]
    #[cfg(feature = "host")]
    Experiment(experiment::ExperimentCommand),
    /// Not in this vl: it was built without the `host` feature.
    #[cfg(not(feature = "host"))]
    Experiment(Missing),
    /// The recorded runs: list, describe, export, repair.
    Record(record::RecordArgs),
}

/// What a command this `vl` was built without takes: anything, to say
/// which feature it needs rather than that it does not exist.
#[derive(clap::Args)]
struct Missing {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    _anything: Vec<std::ffi::OsString>,
}

/// Why `command` cannot run: the cargo feature this `vl` was built without.
fn missing(command: &Command) -> anyhow::Error {
    let (name, feature) = match command {
        Command::Guest(_) => ("guest", "guest"),
        Command::Demo(_) => ("demo", "guest,host"),
        Command::Lti(_) => ("lti", "lti"),
        Command::Host(_) => ("host", "host"),
        Command::Gateway(_) => ("gateway", "gateway"),
        Command::Media(_) => ("media", "host"),
        Command::KheperaEmu(_) => ("khepera-emu", "host"),
        Command::Khepera(_) => ("khepera", "host"),
        Command::SerialGuard(_) => ("serial-guard", "host"),
        Command::Camera(_) => ("camera", "host"),
        Command::Users(_) => ("users", "host"),
        Command::Experiment(_) => ("experiment", "host"),
        _ => ("this command", "default"),
    };
    without(&format!("`vl {name}`"), feature)
}

/// Why `what` cannot be done: this `vl` was built without `feature`.
pub(crate) fn without(what: &str, feature: &str) -> anyhow::Error {
    BadInput(format!(
        "{what} is not in this vl, built without it: \
         build vl with `cargo build --release --features {feature}`"
    ))
    .into()
}

/// Installed for every subcommand but counting only for the Petri commands,
/// which report their peak heap: the Host and the Guest pay nothing for it.
#[global_allocator]
static ALLOCATOR: vl_report::Counting = vl_report::Counting;

/// A problem with what the user gave (a file, an argument): exit code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// `e` as the user's to fix, for `map_err`.
pub(crate) fn bad_input(e: impl std::fmt::Display) -> BadInput {
    BadInput(e.to_string())
}

pub(crate) use named::named_parser as named;
#[cfg(feature = "host")]
pub(crate) use vl_core::{duration, duration_or_none};

fn main() -> ExitCode {
    // `vl host --config lab.toml`: the file's flags, then the command line's.
    let cli =
        match flag_file::with_flag_file(std::env::args_os().collect(), &Cli::command(), "host") {
            Ok(args) => Cli::parse_from(args),
            Err(e) => return report(&BadInput(e.to_string()).into()),
        };
    // Tools end quietly, as Unix filters, when a reader such as `head` closes the pipe;
    // servers outlive clients whose sockets close (TLS writes with writev).
    if !matches!(
        cli.command,
        Command::Host(_)
            | Command::Gateway(_)
            | Command::Guest(_)
            | Command::Demo(_)
            | Command::Media(_)
    ) {
        // SAFETY: restoring the default action of one signal before any thread starts.
        unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    }
    // A file grown past the system's limit (`ulimit -f`) is a failed write
    // the recorder reports, as a full disk, not a signal that kills the lab.
    // SAFETY: ignoring one signal before any thread starts.
    unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
    if matches!(cli.command, Command::Petri(_)) {
        vl_report::Counting::switch_on();
    }
    // Whatever RUST_LOG asks, the WebSocket libraries stay above trace:
    // at trace they print every frame, a hello's password among them.
    let asked = std::env::var("RUST_LOG")
        .ok()
        .filter(|asked| !asked.trim().is_empty())
        .unwrap_or_else(|| "warn".into());
    let capped = if asked.to_lowercase().contains("trace") {
        format!("{asked},tungstenite=debug,tokio_tungstenite=debug")
    } else {
        asked
    };
    let filter = EnvFilter::try_new(&capped).unwrap_or_else(|_| "warn".into());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    run(cli).unwrap_or_else(|e| report(&e))
}

/// Says what went wrong; the user's input exits with 2.
fn report(e: &anyhow::Error) -> ExitCode {
    eprintln!("vl: {e:#}");
    if e.downcast_ref::<BadInput>().is_some() {
        ExitCode::from(2)
    } else {
        ExitCode::FAILURE
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    let runtime = || tokio::runtime::Runtime::new().context("cannot start the async runtime");
    match cli.command {
        Command::Lab(command) => nets::run(command),
        Command::Petri(command) => petri::run(command),
        Command::Sim(command) => sim::run(command),
        Command::Vision(command) => vision::run(command),
        Command::Plan(args) => plan::run(args),
        Command::Controller(command) => controller::run(command),
        Command::Record(command) => record::record(command),
        #[cfg(feature = "guest")]
        Command::Guest(args) => guest::guest(&runtime()?, args),
        #[cfg(all(feature = "guest", feature = "host"))]
        Command::Demo(args) => guest::demo(&runtime()?, args),
        #[cfg(feature = "lti")]
        Command::Lti(command) => lti::run(command),
        #[cfg(feature = "host")]
        command => run_host(command, runtime),
        #[cfg(not(feature = "host"))]
        command => Err(missing(&command)),
    }
}

/// The lab machine's commands.
#[cfg(feature = "host")]
fn run_host(
    command: Command,
    runtime: impl Fn() -> Result<tokio::runtime::Runtime>,
) -> Result<ExitCode> {
    match command {
        Command::Host(command) => runtime()?
            .block_on(host::host_command(*command))
            .map(|()| ExitCode::SUCCESS),
        #[cfg(feature = "gateway")]
        Command::Gateway(args) => {
            let runtime = runtime()?;
            let result = runtime.block_on(gateway::gateway_command(args));
            // Zenoh's tasks may still wait on their peers: a second, not
            // however long they take (Ctrl-C stops the gateway promptly).
            runtime.shutdown_timeout(std::time::Duration::from_secs(1));
            result.map(|()| ExitCode::SUCCESS)
        }
        Command::Media(args) => runtime()?
            .block_on(media::run(args))
            .map(|()| ExitCode::SUCCESS),
        Command::KheperaEmu(args) => khepera::khepera_emu(args),
        Command::Khepera(tool) => khepera::khepera(tool),
        Command::SerialGuard(args) => khepera::serial_guard(args),
        Command::Camera(command) => camera::run(command),
        Command::Experiment(command) => experiment::run(&runtime()?, command),
        Command::Users(command) => access::users(command),
        command => Err(missing(&command)),
    }
}
