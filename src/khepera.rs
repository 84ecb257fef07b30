//! `vl khepera-emu` stands in for the robot on a pseudo-terminal; `vl
//! khepera characterise` measures a real one's speed response; the hidden
//! `vl serial-guard` holds its line for a Host.

use std::process::ExitCode;

use anyhow::{Context, Result};
use vl_core::RobotKind;
use vl_host::KheperaSerial;

use crate::input::{RobotArgs, arena_from};
use crate::report::{Report, Table, emit};
use crate::{bad_input, named};

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
    /// second (`truth T X Y θ CONTACTS`, then `leash T REMAINING TARGET_L
    /// TARGET_R` mm, or `leash T none`): what tests judge a run by, and
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
    // The Host heard of any failure through the pipe already.
    let failed = vl_host::run_guard(&args.port, args.baud).is_err();
    Ok(ExitCode::from(u8::from(failed)))
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
        let mut table = self.fit.table();
        table.row(vec![
            "model".into(),
            format!("wrote {}", self.model_file.display()),
        ]);
        table
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
    let model_file = args.output;
    emit(&Characterised { fit, model_file }, args.json)?;
    Ok(ExitCode::SUCCESS)
}

pub(crate) fn khepera_emu(args: KheperaArgs) -> Result<ExitCode> {
    let model = args.robot.model()?;
    let name = model.name.clone();
    let arena = arena_from(&args.arena, args.start)?;
    let world = vl_sim::World::new(arena, model, args.seed).map_err(bad_input)?;
    let line = vl_sim::PortSettings {
        baud: args.baud,
        timing: !args.instant_line,
        log_commands: args.log_commands,
        truth: args.truth,
    };
    let mut emulator =
        vl_sim::Emulator::open(vl_sim::Khepera::new(world), line, args.link.as_deref())?;
    // Scripts and tests read the device from this first line.
    println!("vl khepera-emu: {name} on {}", emulator.device());
    std::io::Write::flush(&mut std::io::stdout())?;
    // A real robot has a processor of its own: the emulated one asks to run first.
    let priority = vl_host::raise_priority("emulated robot");
    eprintln!("vl khepera-emu: the emulated robot runs at {priority}");
    emulator.run()?;
    Ok(ExitCode::SUCCESS)
}
