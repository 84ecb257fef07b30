//! How much faster than real time the simulator runs (`vl sim bench`).

use std::time::Instant;

use serde::Serialize;
use vl_core::{Arena, ArenaPlanError, Definition, Goal, RobotModel, WheelSpeeds, plan_route};
use vl_report::table::{Report, Table};

use crate::world::{STEP_S, SimError, World};
use crate::{Optics, Renderer, camera_for};

/// Simulated seconds per wall-clock second.
#[derive(Debug, Clone, Serialize)]
pub struct SimBench {
    pub sim_seconds: f64,
    /// The robot and its sensors only.
    pub rtf_no_camera: f64,
    /// The same with a 320×240 camera frame rendered at 30 Hz.
    pub rtf_camera: f64,
    /// A forecast (follower, safety layer, simulator) with
    /// [`FORECAST_SEEDS`] seeds of a navigation run of about a minute: the
    /// navigation arena's planned path at a capped speed. Its runs' mean
    /// simulated seconds, and the wall-clock seconds the forecast took.
    pub forecast_run_s: f64,
    pub forecast_s: f64,
}

/// Why the bench could not run.
#[derive(Debug, thiserror::Error)]
pub enum SimBenchError {
    #[error(transparent)]
    World(#[from] SimError),
    #[error("cannot plan the bench's run: {0}")]
    Plan(#[from] ArenaPlanError),
    #[error(transparent)]
    Forecast(#[from] crate::ForecastError),
}

/// Seeds a forecast runs with, in the bench: as a Host would.
pub const FORECAST_SEEDS: [u64; 5] = [1, 2, 3, 4, 5];

/// Runs the navigation arena for `seconds` of simulated time, once
/// without and once with the camera, driving a slow circle.
pub fn bench(seconds: f64) -> Result<SimBench, SimBenchError> {
    let timed = |camera_hz: Option<f64>| -> Result<f64, SimError> {
        let mut world = World::new(Arena::navigation(), RobotModel::khepera_ii(), 1)?;
        let mut renderer = Renderer::new(camera_for(&world, 320, 30.0), Optics::default());
        let frame_every = camera_hz.map(|hz| ((1.0 / hz) / STEP_S).round().max(1.0) as u64);
        let steps = (seconds / STEP_S) as u64;
        let started = Instant::now();
        let mut frames = 0usize;
        for step in 0..steps {
            if step % 2 == 0 {
                std::hint::black_box(world.proximity());
            }
            // A slow circle keeps the robot moving through the arena.
            world.set_wheels(WheelSpeeds {
                left_mm_s: 120.0,
                right_mm_s: 150.0,
            });
            world.step();
            if frame_every.is_some_and(|every| step % every == 0) {
                frames += std::hint::black_box(renderer.render(&world)).len();
            }
        }
        std::hint::black_box(frames);
        Ok(seconds / started.elapsed().as_secs_f64())
    };
    let (forecast_run_s, forecast_s) = forecast_timed()?;
    Ok(SimBench {
        sim_seconds: seconds,
        rtf_no_camera: timed(None)?,
        rtf_camera: timed(Some(30.0))?,
        forecast_run_s,
        forecast_s,
    })
}

/// The speed, mm/s, at which the bench's forecast follows the navigation
/// arena's planned path (845 mm): about a minute's run.
const FORECAST_SPEED_MM_S: f64 = 17.0;

/// Times a forecast of a minute's navigation run: the mean simulated
/// seconds of its runs, and the wall-clock seconds it took.
fn forecast_timed() -> Result<(f64, f64), SimBenchError> {
    let arena = Arena::navigation();
    let robot = RobotModel::khepera_ii();
    let goal = arena.goal.unwrap_or(arena.start.point());
    let plan = plan_route(&arena, &[], &robot, arena.start, goal)?;
    let definition = Definition {
        goal: Some(Goal::at(goal)),
        path: plan.points(),
        max_speed_mm_s: Some(FORECAST_SPEED_MM_S),
        ..Definition::default()
    };
    let started = Instant::now();
    let forecast = crate::forecast(crate::Forecasting {
        arena: &arena,
        robot: &robot,
        start: arena.start,
        definition: &definition,
        seeds: &FORECAST_SEEDS,
        cancel: None,
        pilot: crate::Pilot::Path,
    })?;
    let took = started.elapsed().as_secs_f64();
    let simulated: f64 = forecast.runs.iter().map(|r| r.seconds).sum();
    Ok((simulated / forecast.runs.len() as f64, took))
}

impl Report for SimBench {
    fn table(&self) -> Table {
        Table::pairs([
            (
                "real-time factor, no camera",
                format!("{:.0}×", self.rtf_no_camera),
            ),
            (
                "with 320×240 camera at 30 Hz",
                format!("{:.0}×", self.rtf_camera),
            ),
            (
                "a forecast, 5 seeds",
                format!(
                    "a {:.0} s run's in {:.2} s (target ≤ 0.5 s)",
                    self.forecast_run_s, self.forecast_s
                ),
            ),
        ])
    }
}
