//! `vl controller …`: a user's own wheel controller, a WebAssembly module
//! (`docs/controllers.md`): checked, tried on the lab's twin as the Host
//! tries it before the robot moves, and timed.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use serde::Serialize;
use vl_core::{
    Arena, Controller, Definition, ForecastLimits, ForecastVerdict, Goal, Observation, Point, Pose,
    RobotModel, STEP_PERIOD_S, WheelSpeeds,
};
use vl_report::table::{Report, Table};
use vl_sandbox::{Budget, Module};
use vl_sim::{FORECAST_SEEDS, Forecasting, Pilot, forecast};

use crate::report::emit;
use crate::{BadInput, bad_input};

#[derive(Subcommand)]
pub(crate) enum ControllerCommand {
    /// Check a module: WebAssembly, its imports and exports, interface
    /// version 1, and that it starts.
    Check {
        /// The module: .wasm, or its text format (.wat).
        file: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Try a module on the lab's twin, as the Host does before the robot
    /// moves: it must finish (or reach the goal) without contact or fault.
    /// Exits 1 when it would be refused.
    Forecast(ForecastArgs),
    /// Time a module's steps at the control rate, against the lab's own
    /// path follower's, and a forecast with it.
    Bench {
        file: PathBuf,
        /// Steps to time.
        #[arg(long, default_value_t = 3000)]
        steps: u32,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args)]
pub(crate) struct ForecastArgs {
    /// The module: .wasm, or its text format (.wat).
    file: PathBuf,
    /// The arena the twin runs in: a shipped one's name.
    #[arg(long, default_value = "navigation")]
    arena: String,
    /// The goal, x,y mm (default: the arena's).
    #[arg(long, allow_hyphen_values = true)]
    goal: Option<Point>,
    /// The run's time limit, s.
    #[arg(long, default_value_t = vl_sim::CONTROLLER_S)]
    time_limit: f64,
    /// Seeds of sensor and wheel noise to try.
    #[arg(long, default_value_t = FORECAST_SEEDS.len() as u32)]
    seeds: u32,
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(command: ControllerCommand) -> Result<ExitCode> {
    match command {
        ControllerCommand::Check { file, json } => {
            let module = load(&file)?;
            module.start(Budget::TWIN).map_err(bad_input)?;
            emit(&Checked::of(&file, &module), json)?;
            Ok(ExitCode::SUCCESS)
        }
        ControllerCommand::Forecast(args) => forecast_module(args),
        ControllerCommand::Bench { file, steps, json } => {
            let module = load(&file)?;
            emit(&bench(&file, &module, steps.max(10))?, json)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Reads and checks a module, its faults the user's to fix.
fn load(file: &std::path::Path) -> Result<Module> {
    let bytes = vl_client::read_controller(file).map_err(bad_input)?;
    Module::load(&bytes).map_err(|e| BadInput(format!("{}: {e}", file.display())).into())
}

/// A module that passed its checks.
#[derive(Serialize)]
struct Checked {
    file: String,
    sha256: String,
    bytes: usize,
    interface: i32,
}

impl Checked {
    fn of(file: &std::path::Path, module: &Module) -> Checked {
        Checked {
            file: file.display().to_string(),
            sha256: module.hash().to_string(),
            bytes: module.len(),
            interface: vl_core::ABI_VERSION,
        }
    }
}

impl Report for Checked {
    fn table(&self) -> Table {
        Table::pairs([
            ("module", self.file.clone()),
            ("sha256", self.sha256.clone()),
            ("bytes", self.bytes.to_string()),
            (
                "interface",
                format!("version {}: checked, and it starts", self.interface),
            ),
        ])
    }
}

/// The module's forecast and the verdict on it.
#[derive(Serialize)]
struct ModuleForecast {
    module: Checked,
    arena: String,
    goal: Option<Point>,
    /// How long the forecast took, s.
    took_s: f64,
    #[serde(flatten)]
    verdict: ForecastVerdict,
}

impl Report for ModuleForecast {
    fn table(&self) -> Table {
        let mut rows = vec![
            ("module", self.module.file.clone()),
            ("sha256", self.module.sha256.clone()),
            ("arena", self.arena.clone()),
        ];
        rows.extend(self.verdict.figures());
        rows.push(("took", format!("{:.2} s", self.took_s)));
        rows.push(("verdict", self.verdict.words()));
        Table::pairs(rows).title("the controller, tried on the lab's twin:")
    }
}

fn forecast_module(args: ForecastArgs) -> Result<ExitCode> {
    let module = load(&args.file)?;
    let arena = Arena::named(&args.arena).ok_or_else(|| {
        BadInput(format!(
            "--arena: no shipped arena {}; there are {}",
            args.arena,
            Arena::shipped().collect::<Vec<_>>().join(", ")
        ))
    })?;
    if !(args.time_limit.is_finite() && (1.0..=vl_sim::LONGEST_S).contains(&args.time_limit)) {
        return Err(BadInput(format!(
            "--time-limit: {} s is not between 1 and {} s",
            args.time_limit,
            vl_sim::LONGEST_S
        ))
        .into());
    }
    let goal = args.goal.or(arena.goal);
    let definition = Definition {
        goal: goal.map(Goal::at),
        time_limit_s: Some(args.time_limit),
        ..Definition::default()
    };
    let seeds: Vec<u64> = (1..=u64::from(args.seeds.clamp(1, 8))).collect();
    let robot = RobotModel::khepera_ii();
    let controllers = module.controllers(Budget::TWIN);
    let began = Instant::now();
    let foreseen = forecast(Forecasting {
        arena: &arena,
        robot: &robot,
        start: arena.start,
        definition: &definition,
        seeds: &seeds,
        cancel: None,
        pilot: Pilot::Controller(&controllers),
    })
    .map_err(bad_input)?;
    let report = ModuleForecast {
        module: Checked::of(&args.file, &module),
        arena: args.arena,
        goal,
        took_s: began.elapsed().as_secs_f64(),
        verdict: ForecastVerdict::new(foreseen, ForecastLimits::default()),
    };
    emit(&report, args.json)?;
    Ok(if report.verdict.passed() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// What a step costs, µs, and a forecast with the module.
#[derive(Serialize)]
struct Bench {
    module: Checked,
    steps: u32,
    step_p50_us: f64,
    step_p99_us: f64,
    /// The lab's own path follower's step, the peer.
    follower_p50_us: f64,
    follower_p99_us: f64,
    /// Instructions a step executed, most.
    fuel_most: u64,
    /// Seeds and simulated seconds of the forecast, and how long it took.
    forecast_seeds: usize,
    forecast_simulated_s: f64,
    forecast_took_s: f64,
}

impl Report for Bench {
    fn table(&self) -> Table {
        Table::pairs([
            ("module", self.module.file.clone()),
            (
                "steps timed",
                format!("{} at {:.0} Hz", self.steps, 1.0 / STEP_PERIOD_S),
            ),
            (
                "a step",
                format!(
                    "p50 {:.1} µs, p99 {:.1} µs",
                    self.step_p50_us, self.step_p99_us
                ),
            ),
            (
                "the lab's follower",
                format!(
                    "p50 {:.1} µs, p99 {:.1} µs (the module ×{:.2} at p50)",
                    self.follower_p50_us,
                    self.follower_p99_us,
                    self.step_p50_us / self.follower_p50_us.max(1e-9)
                ),
            ),
            (
                "fuel, most",
                format!("{} of {} a step", self.fuel_most, Budget::LAB.fuel_per_step),
            ),
            (
                "forecast",
                format!(
                    "{} seeds, {:.0} s simulated, in {:.2} s",
                    self.forecast_seeds, self.forecast_simulated_s, self.forecast_took_s
                ),
            ),
        ])
        .title("a controller's cost:")
    }
}

/// The p-th percentile of sorted `values`.
fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

fn bench(file: &std::path::Path, module: &Module, steps: u32) -> Result<Bench> {
    let arena = Arena::navigation();
    let robot = RobotModel::khepera_ii();
    let goal = arena.goal;
    let mut instance = module.start(Budget::TWIN).map_err(bad_input)?;
    // A robot circling the arena's middle: the observations vary.
    let seen = |i: u32| {
        let a = f64::from(i) * 0.01;
        Observation {
            t_s: f64::from(i) * STEP_PERIOD_S,
            pose: Pose {
                x_mm: 400.0 + 150.0 * a.cos(),
                y_mm: 300.0 + 150.0 * a.sin(),
                theta_rad: a,
            },
            uncertainty_mm: 1.0,
            wheels: WheelSpeeds::default(),
            goal,
            proximity: [0.0; 8],
            period_s: STEP_PERIOD_S,
            speed_limit_mm_s: robot.max_wheel_speed_mm_s,
        }
    };
    let (mut times, mut fuel_most) = (Vec::new(), 0);
    for i in 0..steps {
        let o = seen(i);
        let began = Instant::now();
        instance.step(&o).map_err(bad_input)?;
        times.push(began.elapsed().as_secs_f64() * 1e6);
        fuel_most = fuel_most.max(instance.fuel_used());
    }
    times.sort_by(f64::total_cmp);
    // The peer: the lab's follower stepping along a planned path.
    let start = arena.start;
    let planned = vl_core::plan_route(&arena, &[], &robot, start, goal.unwrap_or_default())
        .map_err(|e| anyhow::anyhow!("planning the follower's path: {e}"))?;
    let definition = Definition {
        goal: goal.map(Goal::at),
        path: planned.points(),
        ..Definition::default()
    };
    let mut follower = vl_core::Follower::for_definition(&definition).context("a path")?;
    let mut peer = Vec::new();
    for i in 0..steps {
        let o = seen(i);
        let began = Instant::now();
        std::hint::black_box(follower.step(&robot, o.pose, &[0; 8]));
        peer.push(began.elapsed().as_secs_f64() * 1e6);
    }
    peer.sort_by(f64::total_cmp);
    let controllers = module.controllers(Budget::TWIN);
    let definition = Definition {
        goal: goal.map(Goal::at),
        time_limit_s: Some(vl_sim::CONTROLLER_S),
        ..Definition::default()
    };
    let began = Instant::now();
    let foreseen = forecast(Forecasting {
        arena: &arena,
        robot: &robot,
        start,
        definition: &definition,
        seeds: &FORECAST_SEEDS,
        cancel: None,
        pilot: Pilot::Controller(&controllers),
    })
    .map_err(bad_input)?;
    Ok(Bench {
        module: Checked::of(file, module),
        steps,
        step_p50_us: percentile(&times, 0.5),
        step_p99_us: percentile(&times, 0.99),
        follower_p50_us: percentile(&peer, 0.5),
        follower_p99_us: percentile(&peer, 0.99),
        fuel_most,
        forecast_seeds: FORECAST_SEEDS.len(),
        forecast_simulated_s: foreseen.runs.iter().map(|r| r.seconds).sum(),
        forecast_took_s: began.elapsed().as_secs_f64(),
    })
}
