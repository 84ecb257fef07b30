//! Go-to-goal steering: turn toward the goal, drive when facing it, slow
//! near it, and let the proximity sensors push the robot away from
//! obstacles the straight line runs into (a Braitenberg-style deflection).

use crate::robot::{Point, Pose, RobotModel, WheelSpeeds, wrap_angle};

/// Gains and speeds for [`go_to_goal`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Steering {
    pub cruise_mm_s: f64,
    /// rad/s of turn per rad of heading error.
    pub turn_gain: f64,
    /// Distance over which the robot slows to a stop at the goal.
    pub slow_radius_mm: f64,
    /// rad/s of turn away from an obstacle at full proximity reading.
    pub avoid_gain: f64,
}

impl Default for Steering {
    fn default() -> Self {
        Steering {
            cruise_mm_s: 300.0,
            turn_gain: 3.0,
            slow_radius_mm: 80.0,
            avoid_gain: 6.0,
        }
    }
}

/// Wheel speeds that take the robot at `pose` toward `goal`, given its
/// latest `proximity` readings (0–1023, higher = nearer).
pub fn go_to_goal(
    robot: &RobotModel,
    pose: Pose,
    goal: Point,
    proximity: &[u16],
    gains: Steering,
) -> WheelSpeeds {
    let dx = goal.x_mm - pose.x_mm;
    let dy = goal.y_mm - pose.y_mm;
    let distance = dx.hypot(dy);
    let error = wrap_angle(dy.atan2(dx) - pose.theta_rad);
    // Each sensor facing forward or sideways turns the robot away from its
    // side; the nearer the obstacle, the less the goal's pull counts, so the
    // robot skirts an obstacle instead of pressing into it toward the goal.
    let mut avoid = 0.0;
    let (mut nearest, mut nearest_front) = (0.0f64, 0.0f64);
    for (mount, &reading) in robot.sensors.iter().zip(proximity) {
        let r = f64::from(reading) / 1023.0;
        if mount.angle_rad.cos() < -0.1 {
            continue; // rear sensors: nothing ahead to avoid
        }
        let side = if mount.y_mm >= 0.0 { -1.0 } else { 1.0 };
        avoid += side * gains.avoid_gain * r * (0.5 + mount.angle_rad.cos());
        nearest = nearest.max(r);
        if mount.angle_rad.abs() < 0.8 {
            nearest_front = nearest_front.max(r);
        }
    }
    let pull = (1.0 - 2.0 * nearest).max(0.0);
    let w = pull * gains.turn_gain * error + avoid;
    let v = gains.cruise_mm_s
        * (distance / gains.slow_radius_mm).clamp(0.15, 1.0)
        * (pull * error.cos().max(0.0) + (1.0 - pull) * 0.6)
        * (1.0 - 2.0 * nearest_front).max(0.0);
    robot.wheels_for(v, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reaches_a_goal_in_open_space() {
        let robot = RobotModel::khepera_ii();
        let goal = Point {
            x_mm: 300.0,
            y_mm: -200.0,
        };
        let mut pose = Pose {
            x_mm: 0.0,
            y_mm: 0.0,
            theta_rad: 2.0,
        };
        for _ in 0..2000 {
            let wheels = go_to_goal(&robot, pose, goal, &[0; 8], Steering::default());
            pose = pose.advance(wheels, robot.wheel_base_mm, 0.01);
        }
        assert!(pose.point().distance(goal) < 10.0, "ended at {pose:?}");
    }

    #[test]
    fn an_obstacle_on_the_left_turns_it_right() {
        let robot = RobotModel::khepera_ii();
        let pose = Pose::default();
        let goal = Point {
            x_mm: 500.0,
            y_mm: 0.0,
        };
        let left_blocked = [0, 900, 600, 0, 0, 0, 0, 0];
        let w = go_to_goal(&robot, pose, goal, &left_blocked, Steering::default());
        assert!(w.left_mm_s > w.right_mm_s);
    }
}
