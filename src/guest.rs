//! `vl guest`: the window, or a scripted Guest without one; `vl demo`
//! runs a Guest against a simulated Host in the same process.

use std::process::ExitCode;
use std::time::Duration;

use anyhow::Result;
use vl_client::{Login, Script, ScriptError, ScriptReport as RunReport};
use vl_core::{ExperimentId, Role};
use vl_guest::{PadChoice, WindowError};
#[cfg(feature = "host")]
use vl_host::{Host, HostConfig, Media, SimLab};

use crate::login::LoginArgs;
#[cfg(feature = "host")]
use crate::media::LinkArgs;
use crate::named::ExperimentParser;
use crate::report::emit;
use crate::{BadInput, bad_input};

#[derive(clap::Args)]
pub(crate) struct GuestArgs {
    /// The Host's WebSocket URL.
    #[arg(long, default_value = "ws://127.0.0.1:7400")]
    connect: String,
    /// Watch only; another person drives.
    #[arg(long)]
    observer: bool,
    #[command(flatten)]
    login: LoginArgs,
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
    gamepad: PadChoice,
    /// Count the gamepad's stick only while its dead-man button (left
    /// shoulder or trigger) is held.
    #[arg(long)]
    dead_man: bool,
    /// Play a recorded run (an .mcap file the Host wrote) back instead of
    /// connecting: in the window, or with --headless to its end.
    #[arg(long, value_hint = clap::ValueHint::FilePath)]
    replay: Option<std::path::PathBuf>,
    /// Experiment to mount for a headless run, by id (a shipped one, or
    /// one the Host serves from a folder): the first the Host offers when
    /// not given.
    #[arg(long, value_parser = ExperimentParser::AnyId)]
    experiment: Option<ExperimentId>,
    #[command(flatten)]
    run: RunArgs,
}

/// The gamepad asked for, said on the console when one is found.
fn gamepad(choice: &PadChoice, dead_man: bool) -> Result<Option<Box<dyn vl_guest::Pad>>> {
    let pad = choice.open(dead_man).map_err(bad_input)?;
    if let Some(pad) = &pad {
        let feel = if pad.has_force_feedback() {
            "with force feedback"
        } else {
            "without force feedback"
        };
        eprintln!("vl guest: driving with {} ({feel})", pad.name());
    }
    Ok(pad)
}

#[cfg(feature = "host")]
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
    /// Experiment to mount for a headless run: the first shipped when not
    /// given.
    #[arg(long, value_parser = ExperimentParser::Shipped)]
    experiment: Option<ExperimentId>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Args)]
pub(crate) struct RunArgs {
    /// Give up a headless run (stop watching, as an observer) after this many seconds.
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    /// Where a headless run drives to, x,y mm (default: the arena's goal).
    #[arg(long, allow_hyphen_values = true)]
    goal: Option<vl_core::Point>,
    /// The points a headless run visits in order, for an experiment that
    /// defines waypoints: x,y mm each, separated by `;` (default: the
    /// fewest it visits, along the path to the goal).
    #[arg(long, value_delimiter = ';', allow_hyphen_values = true)]
    waypoints: Vec<vl_core::Point>,
    /// After a headless run, download its recording into this folder.
    #[arg(long, value_hint = clap::ValueHint::DirPath)]
    download_to: Option<std::path::PathBuf>,
    /// Run the task saved under this name (its experiment and definition)
    /// instead of planning one.
    #[arg(long)]
    task: Option<vl_client::TaskName>,
    /// Save this run's definition as a task of this name.
    #[arg(long)]
    save_task: Option<vl_client::TaskName>,
    /// Your own controller, a WebAssembly module (.wasm, or its text
    /// format), for an experiment whose run it drives: sent to the Host,
    /// tried on its twin, then run on the robot (docs/controllers.md).
    #[arg(long, value_hint = clap::ValueHint::FilePath)]
    controller: Option<std::path::PathBuf>,
}

/// A Guest error: an address that cannot be a Host's is the user's input.
fn guest_error(e: impl Into<anyhow::Error>) -> anyhow::Error {
    let e = e.into();
    let bad = e.downcast_ref().is_some_and(ScriptError::is_bad_input)
        || e.downcast_ref().is_some_and(WindowError::is_bad_address);
    if bad {
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
    if let Some(file) = &args.replay {
        let bad = |e: vl_record::RecordError| BadInput(format!("--replay: {e}"));
        match args.headless {
            true => emit(&vl_client::replay_headless(file).map_err(bad)?, args.json)?,
            false => vl_guest::run_replay_window(vl_client::Replay::open(file).map_err(bad)?)?,
        }
        return Ok(ExitCode::SUCCESS);
    }
    if args.headless {
        let script = script(&args.run, &args.experiment, args.login.login()?, !args.json)?;
        if role == Role::Observer {
            let watched = interruptible(runtime, vl_client::watch(&args.connect, &script))?
                .map_err(guest_error)?;
            emit(&watched, args.json)?;
            return Ok(ExitCode::SUCCESS);
        }
        let report = interruptible(runtime, vl_client::run_script(&args.connect, &script))?
            .map_err(guest_error)?;
        return finish(&report, args.json);
    }
    let pad = gamepad(&args.gamepad, args.dead_man)?;
    let _entered = runtime.enter();
    vl_guest::run_window(&args.connect, role, args.login.login()?, pad).map_err(guest_error)?;
    Ok(ExitCode::SUCCESS)
}

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
                tokio::time::sleep(vl_client::GOODBYE_WAIT).await;
                eprintln!("vl guest: interrupted; said goodbye to the Host");
                std::process::exit(130);
            }
        }
    })
}

#[cfg(feature = "host")]
pub(crate) fn demo(runtime: &tokio::runtime::Runtime, args: DemoArgs) -> Result<ExitCode> {
    use anyhow::Context;
    let listen: std::net::SocketAddr = ([127, 0, 0, 1], 0).into();
    let host = runtime
        .block_on(Host::start_sim(
            listen,
            SimLab {
                seed: args.seed,
                ..SimLab::new(vl_core::Arena::navigation())
            },
            HostConfig::default(),
        ))
        .context("cannot start the simulated Host")?;
    let media = runtime.block_on(args.link.front(listen, &host.url()))?;
    let url = media.as_ref().map_or_else(|| host.url(), Media::url);
    let has_display = vl_guest::display_available();
    if !args.headless && !has_display {
        eprintln!(
            "vl demo: no display (neither DISPLAY nor WAYLAND_DISPLAY is set); running headless"
        );
    }
    if args.headless || !has_display {
        let script = script(&args.run, &args.experiment, Login::default(), !args.json)?;
        let report = interruptible(runtime, vl_client::run_script(&url, &script))??;
        return finish(&report, args.json);
    }
    eprintln!("vl demo: simulated lab at {url}");
    let _entered = runtime.enter();
    let pad = gamepad(&PadChoice::Auto, false)?;
    vl_guest::run_window(&url, Role::Operator, Login::default(), pad)?;
    Ok(ExitCode::SUCCESS)
}

fn script(
    run: &RunArgs,
    experiment: &Option<ExperimentId>,
    login: Login,
    progress: bool,
) -> Result<Script> {
    let controller = match &run.controller {
        Some(file) => Some(
            vl_client::read_controller(file).map_err(|e| BadInput(format!("--controller {e}")))?,
        ),
        None => None,
    };
    Ok(Script {
        experiment: experiment.clone(),
        goal: run.goal.map(vl_core::Goal::at),
        waypoints: run.waypoints.clone(),
        login,
        timeout: Duration::from_secs_f64(run.timeout.clamp(0.0, 1e6)),
        progress,
        download_to: run.download_to.clone(),
        task: vl_client::TaskChoice {
            task: run.task.clone(),
            save_task: run.save_task.clone(),
        },
        controller,
        ..Script::default()
    })
}

/// Prints the run's report; success is the experiment's: the robot at its
/// goal, or a run that ended by its time or a stop.
fn finish(report: &RunReport, json: bool) -> Result<ExitCode> {
    emit(report, json)?;
    if report.succeeded {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("vl: the robot did not reach the goal ({})", report.ending());
        Ok(ExitCode::FAILURE)
    }
}
