//! Every navigation definition tried on the lab's twin before the robot
//! moves (issue 29): the hub asks for a forecast when a definition is
//! given, off its own task; the verdict goes to everyone and fires
//! `forecast_passed` or `forecast_failed` in the lab's net, whose rule lets
//! a run start only on a passed one. When the run ends, its summary says
//! how far it was from the forecast.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use tracing::{info, warn};
use vl_core::{
    Action, Arena, Definition, ErrorCode, ForecastLimits, ForecastVerdict, HostMessage, Pose,
    Readiness, RobotModel, Summary, plan_route,
};
use vl_sim::{ForecastError, Forecasting, forecast};

use super::Hub;

/// How much less a forecast counts than the control loop, in nice levels.
/// Linux's SCHED_IDLE served the operator a little better (1.14× the quiet
/// p99 against 1.2×) but starved forecasts on a loaded machine, and with
/// them the operator's Start.
const FORECAST_NICE: i32 = 10;
/// A path whose first point is further than this from where the next run
/// starts, mm, is planned again from there after a run.
const REFIT_MM: f64 = 20.0;

/// The most seeds a forecast takes, whatever the lab asks.
pub const MOST_SEEDS: u32 = 8;

/// What a lab asks of a navigation definition's forecast before a run
/// may start, besides reaching the goal without contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForecastSettings {
    /// The least room, mm, the forecast robot may come to anything.
    pub min_clearance_mm: f64,
    /// The longest a run may be forecast to take.
    pub max_run: Option<Duration>,
    /// How many seeds of sensor and wheel noise each forecast tries
    /// (at most [`MOST_SEEDS`]).
    pub forecast_seeds: u32,
}

impl ForecastSettings {
    pub fn limits(&self) -> ForecastLimits {
        ForecastLimits {
            min_clearance_mm: self.min_clearance_mm,
            max_seconds: self.max_run.map(|d| d.as_secs_f64()),
        }
    }
}

impl Default for ForecastSettings {
    fn default() -> Self {
        ForecastSettings {
            min_clearance_mm: 0.0,
            max_run: None,
            forecast_seeds: 5,
        }
    }
}

/// A job's result: the verdict, or why there is none.
pub(crate) type Forecasted = Result<ForecastVerdict, ForecastError>;

/// One forecast, as the Host makes it off the hub.
pub(crate) struct ForecastJob {
    pub(crate) arena: Arena,
    pub(crate) robot: RobotModel,
    pub(crate) start: Pose,
    pub(crate) definition: Definition,
    pub(crate) settings: ForecastSettings,
    /// The user's controller, which drives the run when there is one.
    pub(crate) controller: Option<std::sync::Arc<vl_sandbox::Module>>,
}

impl ForecastJob {
    /// Makes the forecast, on a thread below the control loop and the
    /// operator's commands (it can take a core for a while), yet sure of a
    /// share of a busy machine: an operator waits for it to start a run.
    /// `cancel` ends it early.
    pub(crate) fn run(&self, cancel: &AtomicBool) -> Forecasted {
        crate::priority::yield_to_control(FORECAST_NICE, "forecast");
        let seeds = 1..=u64::from(self.settings.forecast_seeds.clamp(1, MOST_SEEDS));
        let seeds: Vec<u64> = seeds.collect();
        // Each seed's run gets a fresh instance, as each live run does.
        let controllers =
            (self.controller.as_ref()).map(|m| m.controllers(vl_sandbox::Budget::TWIN));
        let pilot = match &controllers {
            Some(controllers) => vl_sim::Pilot::Controller(controllers),
            None => vl_sim::Pilot::Path,
        };
        let forecast = forecast(Forecasting {
            arena: &self.arena,
            robot: &self.robot,
            start: self.start,
            definition: &self.definition,
            seeds: &seeds,
            cancel: Some(cancel),
            pilot,
        })?;
        Ok(ForecastVerdict::new(forecast, self.settings.limits()))
    }
}

impl Hub {
    /// Tries `definition` on the twin, off the hub; a forecast under way
    /// for an older definition is cancelled.
    pub(super) fn ask_forecast(&mut self, definition: &Definition) {
        self.verdict = None;
        let controller = self
            .named_controller(definition)
            .ok()
            .flatten()
            .map(|t| t.module);
        // Without a path or a controller the operator's own commands drive,
        // guarded live by the safety layer as in teleoperation: nothing to
        // foresee.
        if definition.path.is_empty() && controller.is_none() {
            self.forecasts.forget();
            return self.happened(Action::ForecastPassed);
        }
        let start = self.next_start();
        let info = &self.lab.info;
        let job = ForecastJob {
            arena: info.arena.clone(),
            robot: info.robot.clone(),
            start,
            definition: definition.clone(),
            settings: self.config.forecast,
            controller,
        };
        self.forecasts
            .ask(move |cancel: &AtomicBool| job.run(cancel));
    }

    /// Where the next run starts: where the robot stands, or the start
    /// pose while it drives back there. Forecasts and plans start here.
    pub(super) fn next_start(&self) -> Pose {
        match (self.readiness, self.robot_pose()) {
            (Readiness::Ready, Some(pose)) => pose,
            _ => self.lab.info.arena.start,
        }
    }

    /// After a run, the definition for the next: as it was, unless its
    /// path began where the next run does not (the robot drove back to its
    /// start, or stopped elsewhere) — then planned again from there to the
    /// same goal, so the twin tries what the robot can follow and the path
    /// drawn starts at the robot.
    pub(super) fn refit(&mut self, definition: Definition) -> Definition {
        let start = self.next_start();
        let (Some(first), Some(goal)) = (definition.path.first(), definition.goal) else {
            return definition;
        };
        if first.distance(start.point()) <= REFIT_MM {
            return definition;
        }
        let info = &self.lab.info;
        let plan = plan_route(
            &info.arena,
            &definition.virtual_obstacles,
            &info.robot,
            start,
            goal.point(),
        );
        let Ok(plan) = plan else {
            return definition;
        };
        info!("the path began where the next run does not: planned again to the same goal");
        let refitted = Definition {
            path: plan.points(),
            ..definition
        };
        self.definition = Some(refitted.clone());
        self.broadcast(&HostMessage::Defined {
            definition: refitted.clone(),
        });
        refitted
    }

    /// A forecast ended: the newest one's verdict is told and fired.
    pub(super) fn forecast_done(&mut self, number: u64, forecasted: Forecasted) {
        let Some(forecasted) = self.forecasts.finished(number, forecasted) else {
            return;
        };
        let verdict = match forecasted {
            Ok(verdict) => verdict,
            Err(e) => {
                warn!("no forecast for the definition: {e}");
                if let Some(operator) = self.operator {
                    let why = format!("the definition cannot be tried on the lab's twin: {e}");
                    self.refuse(operator, ErrorCode::InvalidDefinition, why);
                }
                return self.happened(Action::ForecastFailed);
            }
        };
        let passed = verdict.passed();
        info!(
            passed,
            reached = verdict.forecast.reached(),
            "forecast of the definition"
        );
        self.broadcast(&HostMessage::Forecast(Box::new(verdict.clone())));
        if let (false, Some(operator)) = (passed, self.operator) {
            let why = format!(
                "the definition, tried on the lab's twin, is {}; define another",
                verdict.words()
            );
            self.refuse(operator, ErrorCode::ForecastRefused, why);
        }
        self.verdict = Some(verdict);
        self.happened(match passed {
            true => Action::ForecastPassed,
            false => Action::ForecastFailed,
        });
    }

    /// Puts in `summary` how far its run was from the forecast.
    pub(super) fn compare_with_forecast(&self, summary: &mut Summary) {
        summary.forecast = self.verdict.as_ref().and_then(|v| v.forecast.gap(summary));
    }
}
