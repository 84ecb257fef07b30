//! How much faster than real time the simulator runs (`vl sim bench`).

use std::time::Instant;

use serde::Serialize;
use vl_core::table::{Report, Table};
use vl_core::{Arena, RobotModel, WheelSpeeds};

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
}

/// Runs the navigation arena for `seconds` of simulated time, once
/// without and once with the camera, driving a slow circle.
pub fn bench(seconds: f64) -> Result<SimBench, SimError> {
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
    Ok(SimBench {
        sim_seconds: seconds,
        rtf_no_camera: timed(None)?,
        rtf_camera: timed(Some(30.0))?,
    })
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
        ])
    }
}
