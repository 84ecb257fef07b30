//! How far odometry drifts from the truth (`vl sim odometry`): the robot
//! drives UMBmark's 1 m square (Borenstein & Feng, 1996) both ways, its
//! encoders count the wheels' turning while slip moves the body less, and
//! each wheel's error per √mm of travel is fitted to the heading errors
//! found. The Host's pose estimate grows its uncertainty by that figure
//! (`RobotModel::wheel_slip`) while no camera watches.

use serde::Serialize;
use vl_core::{Arena, Pose, RobotModel, WheelSpeeds, wrap_angle};
use vl_report::table::{Report, Table};

use crate::world::{STEP_S, SimError, World};

/// The square's side, mm (UMBmark's is 4 m; the arena is 1 m).
const SIDE_MM: f64 = 300.0;
/// Driving speed along a side, mm/s: the path follower's cruise.
const CRUISE_MM_S: f64 = 200.0;
/// Wheel speed when turning in place at a corner, mm/s.
const TURN_MM_S: f64 = 60.0;

/// What the squares showed.
#[derive(Debug, Clone, Serialize)]
pub struct OdometryFit {
    pub squares: usize,
    /// Standard deviation of a wheel's travel error per √mm travelled:
    /// the figure `RobotModel::wheel_slip` holds.
    pub wheel_slip: f64,
    /// Where odometry put the robot at each square's end against where it
    /// was, mm: mean and largest.
    pub end_error_mean_mm: f64,
    pub end_error_max_mm: f64,
    /// The heading error at the squares' ends, rad: root mean square.
    pub heading_error_rms_rad: f64,
}

/// Drives `squares` squares (alternately clockwise and counter-clockwise)
/// on an open floor, each from a fresh seed.
pub fn measure_odometry(robot: &RobotModel, squares: usize) -> Result<OdometryFit, SimError> {
    let start = Pose {
        x_mm: 500.0,
        y_mm: 500.0,
        theta_rad: 0.0,
    };
    let mut arena = Arena::navigation();
    arena.obstacles.clear();
    arena.width_mm = 1000.0;
    arena.height_mm = 1000.0;
    arena.start = Pose {
        x_mm: start.x_mm - SIDE_MM / 2.0,
        y_mm: start.y_mm - SIDE_MM / 2.0,
        ..start
    };
    let (mut heading_sq, mut travel, mut errors) = (0.0, 0.0, Vec::with_capacity(squares));
    for square in 0..squares {
        let mut world = World::new(arena.clone(), robot.clone(), 0x0D0 + square as u64)?;
        let turn = if square % 2 == 0 { 1.0 } else { -1.0 };
        let mut odometry = world.pose();
        let mut counted = world.wheel_travel_mm();
        // One step, its wheels' turning counted as the encoders count it.
        let mut step = |world: &mut World| {
            world.step();
            let now = world.wheel_travel_mm();
            let moved = WheelSpeeds {
                left_mm_s: now[0] - counted[0],
                right_mm_s: now[1] - counted[1],
            };
            counted = now;
            odometry = odometry.advance(moved, robot.wheel_base_mm, 1.0);
            now
        };
        let mut drive =
            |world: &mut World, wheels: WheelSpeeds, done: &dyn Fn(f64, f64) -> bool| {
                let from = world.wheel_travel_mm();
                world.set_wheels(wheels);
                loop {
                    let now = step(world);
                    if done(now[0] - from[0], now[1] - from[1]) {
                        break;
                    }
                }
                world.set_wheels(WheelSpeeds::default());
                for _ in 0..(0.2 / STEP_S) as usize {
                    step(world);
                }
            };
        let quarter = std::f64::consts::FRAC_PI_2 * robot.wheel_base_mm / 2.0;
        for _ in 0..4 {
            let straight = WheelSpeeds {
                left_mm_s: CRUISE_MM_S,
                right_mm_s: CRUISE_MM_S,
            };
            drive(&mut world, straight, &|l, r| (l + r) / 2.0 >= SIDE_MM);
            let spin = WheelSpeeds {
                left_mm_s: -turn * TURN_MM_S,
                right_mm_s: turn * TURN_MM_S,
            };
            drive(&mut world, spin, &|l, r| (r - l).abs() / 2.0 >= quarter);
        }
        let truth = world.pose();
        let travelled = world.wheel_travel_mm();
        heading_sq += wrap_angle(odometry.theta_rad - truth.theta_rad).powi(2);
        travel += travelled[0].abs() + travelled[1].abs();
        errors.push(odometry.point().distance(truth.point()));
    }
    let n = squares.max(1) as f64;
    // A wheel's error has variance k²·travel; the heading's is the two
    // wheels' summed over the wheel base squared.
    let wheel_slip = (heading_sq * robot.wheel_base_mm.powi(2) / travel.max(1e-9)).sqrt();
    Ok(OdometryFit {
        squares,
        wheel_slip,
        end_error_mean_mm: errors.iter().sum::<f64>() / n,
        end_error_max_mm: errors.iter().copied().fold(0.0, f64::max),
        heading_error_rms_rad: (heading_sq / n).sqrt(),
    })
}

impl Report for OdometryFit {
    fn table(&self) -> Table {
        Table::pairs([
            ("squares driven", self.squares.to_string()),
            (
                "wheel slip",
                format!("{:.4} mm per √mm travelled", self.wheel_slip),
            ),
            (
                "end position error",
                format!(
                    "mean {:.1} mm, max {:.1} mm",
                    self.end_error_mean_mm, self.end_error_max_mm
                ),
            ),
            (
                "end heading error",
                format!("{:.2}° rms", self.heading_error_rms_rad.to_degrees()),
            ),
        ])
        .title("odometry against the truth, 300 mm squares at 200 mm/s:")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fitted_slip_is_what_the_simulator_slips_by() {
        let fit = measure_odometry(&RobotModel::khepera_ii(), 60).unwrap();
        // Each wheel's ground speed is off by 1 % per 10 ms step: a step of
        // d mm errs by 0.01·d, so k² = 1e-4·d with d = 2 mm at cruise and
        // less at corners.
        assert!((0.007..0.02).contains(&fit.wheel_slip), "{fit:?}");
        assert!(
            fit.end_error_mean_mm > 0.0 && fit.end_error_max_mm < 30.0,
            "{fit:?}"
        );
    }
}
