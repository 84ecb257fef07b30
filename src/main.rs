//! `vl`: the virtual laboratory's one binary. `vl host` serves the lab,
//! `vl guest` is the user's desktop app, `vl demo` runs both on the
//! simulated lab; the tool subcommands reach the libraries' algorithms.
//! This crate only parses, dispatches and prints.

mod camera;
mod experiment;
mod guest;
mod host;
mod input;
mod khepera;
mod media;
mod nets;
mod petri;
mod plan;
mod report;
mod shipped;
mod sim;
mod vision;

use std::marker::PhantomData;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::builder::{PossibleValue, TypedValueParser};
use clap::{Parser, Subcommand};
use vl_core::Named;

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
    Host(Box<host::HostCommand>),
    /// Open the Guest window on a Host (on the user's desktop).
    Guest(guest::GuestArgs),
    /// Run a Host on the simulated lab and a Guest against it, in one process.
    Demo(guest::DemoArgs),
    /// Relay Guests to a Host through a modelled Internet link (the Media).
    Media(media::MediaCommand),
    /// The labs' own nets: statecharts to the controlled nets the Host runs.
    #[command(subcommand)]
    Lab(nets::LabCommand),
    /// Analyse Petri nets (PNML).
    #[command(subcommand)]
    Petri(petri::PetriCommand),
    /// Emulate a Khepera II on a pseudo-terminal, backed by the simulator.
    KheperaEmu(khepera::KheperaArgs),
    /// Tools for a real Khepera on its serial line.
    #[command(subcommand)]
    Khepera(khepera::KheperaTool),
    /// Holds a robot's serial line for `vl host` (started by it).
    #[command(hide = true)]
    SerialGuard(khepera::GuardArgs),
    /// The simulator's tools: scripted runs, camera frames, link models, speed.
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// Vision on camera frames: components, moments, the robot's pose.
    #[command(subcommand)]
    Vision(vision::VisionCommand),
    /// Plan a path on a top-view map: C-space, NF1, spline, clearance.
    Plan(plan::PlanArgs),
    /// Calibrate the overhead camera: its map from floor mm to pixels.
    #[command(subcommand)]
    Camera(camera::CameraCommand),
    /// Run the lab's experiments headless on the simulator and measure them.
    #[command(subcommand)]
    Experiment(experiment::ExperimentCommand),
}

#[global_allocator]
static ALLOCATOR: vl_petri::Counting = vl_petri::Counting;

/// A problem with what the user gave (a file, an argument): exit code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Parses an address to listen on, suggesting the form when it is not one
/// (`localhost` is a name, not an address and port).
fn listen_address(text: &str) -> Result<std::net::SocketAddr, String> {
    text.parse().map_err(|_| {
        let port = text.rsplit_once(':').map_or("7400", |(_, p)| p);
        format!(
            "'{text}' is not an address and port: give 127.0.0.1:{port} for this machine only, \
             or 0.0.0.0:{port} for every network it is on"
        )
    })
}

/// Parses a [`Named`] value by its id, listing the ids in `--help` and in
/// the error for one that names nothing.
#[derive(Clone)]
pub(crate) struct NamedParser<T>(PhantomData<T>);

pub(crate) fn named<T: Named + Send + Sync + Clone>() -> NamedParser<T> {
    NamedParser(PhantomData)
}

impl<T: Named + Send + Sync + Clone> TypedValueParser for NamedParser<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<T, clap::Error> {
        let text = value.to_string_lossy();
        T::from_id(&text).map_err(|e| {
            let mut error = clap::Error::new(clap::error::ErrorKind::InvalidValue).with_cmd(cmd);
            if let Some(arg) = arg {
                error.insert(
                    clap::error::ContextKind::InvalidArg,
                    clap::error::ContextValue::String(arg.to_string()),
                );
            }
            error.insert(
                clap::error::ContextKind::InvalidValue,
                clap::error::ContextValue::String(text.into_owned()),
            );
            error.insert(
                clap::error::ContextKind::ValidValue,
                clap::error::ContextValue::Strings(e.known.iter().map(|s| s.to_string()).collect()),
            );
            if let Some(now) = e.now {
                error.insert(
                    clap::error::ContextKind::Suggested,
                    clap::error::ContextValue::StyledStrs(vec![
                        format!("'{}' is called '{now}' now", e.name).into(),
                    ]),
                );
            }
            error
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::ALL.iter().map(|v| PossibleValue::new(v.id()))))
    }
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
        // Colour codes only where a terminal shows them, not in a log file.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
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
        Command::Host(command) => runtime()?
            .block_on(host::host_command(*command))
            .map(|()| ExitCode::SUCCESS),
        Command::Guest(args) => guest::guest(&runtime()?, args),
        Command::Demo(args) => guest::demo(&runtime()?, args),
        Command::Media(args) => runtime()?
            .block_on(media::run(args))
            .map(|()| ExitCode::SUCCESS),
        Command::Lab(command) => nets::run(command),
        Command::Petri(command) => petri::run(command),
        Command::KheperaEmu(args) => khepera::khepera_emu(args),
        Command::Khepera(tool) => khepera::khepera(tool),
        Command::SerialGuard(args) => khepera::serial_guard(args),
        Command::Sim(command) => sim::run(command),
        Command::Vision(command) => vision::run(command),
        Command::Plan(args) => plan::run(args),
        Command::Camera(command) => camera::run(command),
        Command::Experiment(command) => experiment::run(&runtime()?, command),
    }
}
