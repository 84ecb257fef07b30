//! Path following: steering a differential-drive robot along a planned path
//! from pose estimates. The angle between the robot's heading and the line
//! to a look-ahead point on the path sets the wheel speeds; the robot slows
//! near the goal, stops within a tolerance, and defers to its proximity
//! sensors when something the map did not show comes close.

use crate::{Definition, Point, Pose, RobotModel, WheelSpeeds, distance_to_polyline, wrap_angle};

/// Room to leave between the robot's body and mapped obstacles when
/// planning a path to follow: there the proximity readings stay under
/// [`Following::unmapped_above`], so only unmapped obstacles make the
/// sensors take over.
pub const PLAN_MARGIN_MM: f64 = 25.0;

/// Gains, speeds and distances for a [`Follower`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Following {
    pub cruise_mm_s: f64,
    /// How far ahead along the path the robot aims.
    pub lookahead_mm: f64,
    /// rad/s of turn per rad of heading error.
    pub turn_gain: f64,
    /// Within this distance of the goal the robot slows down.
    pub slow_radius_mm: f64,
    /// Within this distance of the goal it stops.
    pub tolerance_mm: f64,
    /// Proximity readings (0–1023) above this mean something nearer than
    /// the plan allowed for: the sensors take over in proportion.
    pub unmapped_above: u16,
    /// rad/s of turn away from an obstacle at full reading.
    pub avoid_gain: f64,
    /// Readings above this (an obstacle a few cm away, mapped or not) slow
    /// the robot, to 40 % of its speed at the highest reading: in a tight
    /// passage a small tracking error is a collision.
    pub cautious_above: u16,
}

impl Default for Following {
    fn default() -> Self {
        Following {
            cruise_mm_s: 200.0,
            lookahead_mm: 30.0,
            turn_gain: 6.0,
            slow_radius_mm: 80.0,
            tolerance_mm: 10.0,
            unmapped_above: 600,
            avoid_gain: 6.0,
            cautious_above: 250,
        }
    }
}

/// What the follower asks of the robot this period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Steer {
    Drive(WheelSpeeds),
    /// Within tolerance of the goal: stop.
    Arrived,
}

impl Steer {
    /// The wheel speeds this asks for: none once arrived.
    pub fn wheels(self) -> WheelSpeeds {
        match self {
            Steer::Drive(wheels) => wheels,
            Steer::Arrived => WheelSpeeds::default(),
        }
    }
}

/// Follows one path, remembering how far along it the robot has come so it
/// never skips ahead to a later part of the path that passes close by.
#[derive(Debug, Clone)]
pub struct Follower {
    path: Vec<Point>,
    /// Arc length from the start to each point.
    arc: Vec<f64>,
    /// Index of the path point nearest the robot, never decreasing.
    progress: usize,
    gains: Following,
}

impl Follower {
    /// A follower along a defined path, stopping within half the goal's
    /// tolerance so the Host counts the run as arrived; None without a path.
    pub fn for_definition(definition: &Definition) -> Option<Follower> {
        let tolerance_mm = definition
            .goal
            .map_or(Following::default().tolerance_mm, |g| g.tolerance_mm / 2.0);
        Follower::new(
            definition.path.clone(),
            Following {
                tolerance_mm,
                lookahead_mm: definition
                    .lookahead_mm
                    .unwrap_or(Following::default().lookahead_mm),
                ..Following::default()
            },
        )
    }

    /// A follower for `path` (start to goal); None for an empty path.
    pub fn new(path: Vec<Point>, gains: Following) -> Option<Follower> {
        path.first()?;
        let mut arc = Vec::with_capacity(path.len());
        let mut total = 0.0;
        for (i, p) in path.iter().enumerate() {
            if i > 0 {
                total += path[i - 1].distance(*p);
            }
            arc.push(total);
        }
        Some(Follower {
            path,
            arc,
            progress: 0,
            gains,
        })
    }

    /// How long the path takes at cruising speed, or at `cap` (mm/s) if
    /// that is slower, s.
    pub fn expected_seconds(&self, cap: Option<f64>) -> f64 {
        let speed = cap.map_or(self.gains.cruise_mm_s, |cap| {
            cap.min(self.gains.cruise_mm_s)
        });
        self.arc.last().copied().unwrap_or(0.0) / speed.max(1e-9)
    }

    pub fn goal(&self) -> Point {
        *self.path.last().expect("a follower's path is never empty")
    }

    /// Wheel speeds for the robot at `pose` with its latest `proximity`
    /// readings.
    pub fn step(&mut self, robot: &RobotModel, pose: Pose, proximity: &[u16]) -> Steer {
        let g = self.gains;
        let here = pose.point();
        let to_goal = here.distance(self.goal());
        if to_goal <= g.tolerance_mm {
            return Steer::Arrived;
        }
        self.advance(here);
        let aim = self.lookahead_point();
        let error = wrap_angle((aim.y_mm - pose.y_mm).atan2(aim.x_mm - pose.x_mm) - pose.theta_rad);
        let slow = (to_goal / g.slow_radius_mm).clamp(0.25, 1.0);
        // Facing away from the aim point, turn in place first.
        let mut v = g.cruise_mm_s * slow * error.cos().max(0.0).powi(2);
        let mut w = g.turn_gain * error;
        let sensed = Avoidance::sense(robot, proximity, g.unmapped_above);
        w = (1.0 - sensed.nearest) * w + g.avoid_gain * sensed.turn;
        v *= 1.0 - sensed.nearest_front;
        let near = Avoidance::sense(robot, proximity, g.cautious_above).nearest;
        v *= 1.0 - 0.6 * near;
        Steer::Drive(robot.wheels_for(v, w))
    }

    /// Moves `progress` to the nearest path point within reach ahead.
    fn advance(&mut self, here: Point) {
        let window = self.arc[self.progress] + 2.0 * self.gains.lookahead_mm;
        let mut best = (here.distance(self.path[self.progress]), self.progress);
        for i in self.progress + 1..self.path.len() {
            if self.arc[i] > window {
                break;
            }
            let d = here.distance(self.path[i]);
            if d < best.0 {
                best = (d, i);
            }
        }
        self.progress = best.1;
    }

    /// The first path point a look-ahead distance beyond the progress point.
    fn lookahead_point(&self) -> Point {
        let target = self.arc[self.progress] + self.gains.lookahead_mm;
        let i = self.arc.partition_point(|&a| a < target);
        self.path[i.min(self.path.len() - 1)]
    }

    /// How far along the path the robot has come, mm.
    pub fn progress_mm(&self) -> f64 {
        self.arc[self.progress]
    }

    /// The path's points from the robot's progress to `mm` beyond it.
    pub fn ahead(&self, mm: f64) -> &[Point] {
        let end = self
            .arc
            .partition_point(|&a| a <= self.arc[self.progress] + mm);
        &self.path[self.progress..end.max(self.progress + 1)]
    }

    /// Distance from `p` to the path (its polyline): the tracking error.
    pub fn distance_to_path(&self, p: Point) -> f64 {
        distance_to_polyline(&self.path, p)
    }
}

/// What the forward and side proximity sensors say about nearby obstacles,
/// counting only readings above a threshold.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Avoidance {
    /// Turn away from the obstacles (positive left), 0–about 2.
    pub turn: f64,
    /// Strongest counted reading, 0–1.
    pub nearest: f64,
    /// Strongest counted reading of the sensors facing forward, 0–1.
    pub nearest_front: f64,
}

impl Avoidance {
    /// Each sensor facing forward or sideways turns the robot away from its
    /// side, more the nearer the obstacle (a Braitenberg-style deflection).
    pub(crate) fn sense(robot: &RobotModel, proximity: &[u16], above: u16) -> Avoidance {
        let mut a = Avoidance::default();
        let span = f64::from(1023u16.saturating_sub(above).max(1));
        for (mount, &reading) in robot.sensors.iter().zip(proximity) {
            if mount.angle_rad.cos() < -0.1 {
                continue; // rear sensors: nothing ahead to avoid
            }
            let r = (f64::from(reading.saturating_sub(above)) / span).min(1.0);
            let side = if mount.y_mm >= 0.0 { -1.0 } else { 1.0 };
            a.turn += side * r * (0.5 + mount.angle_rad.cos());
            a.nearest = a.nearest.max(r);
            if mount.angle_rad.abs() < 0.8 {
                a.nearest_front = a.nearest_front.max(r);
            }
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x_mm: f64, y_mm: f64) -> Point {
        Point { x_mm, y_mm }
    }

    /// An L-shaped path sampled every 5 mm.
    fn ell() -> Vec<Point> {
        let mut path: Vec<Point> = (0..=60).map(|i| p(f64::from(i) * 5.0, 0.0)).collect();
        path.extend((1..=60).map(|i| p(300.0, f64::from(i) * 5.0)));
        path
    }

    #[test]
    fn follows_a_corner_and_stops_at_the_goal() {
        let robot = RobotModel::khepera_ii();
        let mut follower = Follower::new(ell(), Following::default()).unwrap();
        let mut pose = Pose {
            x_mm: 0.0,
            y_mm: 10.0,
            theta_rad: 0.5,
        };
        let mut worst: f64 = 0.0;
        let mut arrived = false;
        for _ in 0..3000 {
            match follower.step(&robot, pose, &[0; 8]) {
                Steer::Arrived => {
                    arrived = true;
                    break;
                }
                Steer::Drive(wheels) => pose = pose.advance(wheels, robot.wheel_base_mm, 0.01),
            }
            worst = worst.max(follower.distance_to_path(pose.point()));
        }
        assert!(arrived, "ended at {pose:?}");
        assert!(pose.point().distance(p(300.0, 300.0)) <= 10.0);
        assert!(worst < 30.0, "strayed {worst} mm from the path");
    }

    #[test]
    fn near_readings_slow_the_robot_only_unmapped_ones_steer_it() {
        let robot = RobotModel::khepera_ii();
        let mut follower = Follower::new(ell(), Following::default()).unwrap();
        let pose = Pose::default();
        let mut drive = |proximity: [u16; 8]| match follower.step(&robot, pose, &proximity) {
            Steer::Drive(wheels) => wheels,
            Steer::Arrived => panic!("not there yet"),
        };
        let clear = drive([0; 8]);
        assert_eq!(
            drive([200, 200, 200, 0, 0, 0, 0, 0]),
            clear,
            "noise changes nothing"
        );
        // A mapped wall a few cm to the left: slower, on the same course.
        let near = drive([400, 0, 0, 0, 0, 0, 0, 0]);
        assert!(near.left_mm_s < clear.left_mm_s);
        assert_eq!(near.left_mm_s, near.right_mm_s);
        // Something much nearer than the plan allowed: it turns away (right).
        let blocked = drive([0, 1000, 900, 0, 0, 0, 0, 0]);
        assert!(
            blocked.left_mm_s > blocked.right_mm_s,
            "an obstacle on the left turns it right: {blocked:?}"
        );
    }

    #[test]
    fn progress_never_jumps_to_a_later_part_passing_close() {
        // A hairpin: out along y = 0 and back along y = 30.
        let mut path: Vec<Point> = (0..=40).map(|i| p(f64::from(i) * 5.0, 0.0)).collect();
        path.extend((0..=40).rev().map(|i| p(f64::from(i) * 5.0, 30.0)));
        let mut follower = Follower::new(path, Following::default()).unwrap();
        // Standing near the start but nearer the way back, it still aims ahead on the way out.
        let pose = Pose {
            x_mm: 10.0,
            y_mm: 20.0,
            theta_rad: 0.0,
        };
        follower.step(&RobotModel::khepera_ii(), pose, &[0; 8]);
        assert!(follower.lookahead_point().y_mm == 0.0);
    }
}
