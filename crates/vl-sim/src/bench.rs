//! How much faster than real time the simulator runs (`vl sim bench`).

use std::time::Instant;

use serde::Serialize;
use vl_core::table::{Report, Table};
use vl_core::{Arena, ArenaPlanError, Definition, Goal, RobotModel, WheelSpeeds, plan_route};

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
    /// A forecast (follower, safety layer, simulator) of the navigation
    /// arena's planned run with [`FORECAST_SEEDS`] seeds: the simulated
    /// seconds it covered, the wall-clock milliseconds it took, and so
    /// how long a 60 s run's forecast with as many seeds takes, s.
    pub forecast_sim_seconds: f64,
    pub forecast_ms: f64,
    pub forecast_60s_run_s: f64,
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
    let (forecast_sim_seconds, forecast_ms) = forecast_timed()?;
    Ok(SimBench {
        sim_seconds: seconds,
        rtf_no_camera: timed(None)?,
        rtf_camera: timed(Some(30.0))?,
        forecast_sim_seconds,
        forecast_ms,
        forecast_60s_run_s: 60.0 * FORECAST_SEEDS.len() as f64 * forecast_ms
            / 1e3
            / forecast_sim_seconds,
    })
}

/// Times a forecast of the navigation arena's run from its start to its
/// goal, as planned: simulated seconds, wall-clock ms.
fn forecast_timed() -> Result<(f64, f64), SimBenchError> {
    let arena = Arena::navigation();
    let robot = RobotModel::khepera_ii();
    let goal = arena.goal.unwrap_or(arena.start.point());
    let plan = plan_route(&arena, &[], &robot, arena.start, goal)?;
    let definition = Definition {
        goal: Some(Goal::at(goal)),
        path: plan.points(),
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
    })?;
    let ms = started.elapsed().as_secs_f64() * 1e3;
    let simulated = forecast.runs.iter().map(|r| r.seconds).sum();
    Ok((simulated, ms))
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
                    "{:.1} s of runs in {:.1} ms: a 60 s run's in {:.2} s",
                    self.forecast_sim_seconds, self.forecast_ms, self.forecast_60s_run_s
                ),
            ),
        ])
    }
}
