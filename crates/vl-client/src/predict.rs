//! The predictive display's model (thesis C.1): where the robot is *now*,
//! while the feedback describing it is still on its way. The last feedback
//! tells where the robot was one one-way delay before it arrived; the
//! commands sent since reach the robot one one-way delay after they left.
//! Forward kinematics through the robot's speed response, and the Host's
//! watchdog, carry the pose from then to now.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use vl_core::{Pose, RobotModel, WATCHDOG, WheelSpeeds};

/// Commands kept while unacknowledged: a time-based Guest on a slow link
/// has a few seconds' worth in flight.
const IN_FLIGHT: usize = 1024;
/// The integration step, s: the lab's control period.
const STEP_S: f64 = 0.01;
/// How much a new round trip moves the one-way estimate.
const SMOOTHING: f64 = 0.1;
/// What was shown, kept until the feedback that tells the truth of it
/// arrives: a few seconds of feedback on the slowest link.
const SHOWN_KEPT: usize = 4096;

/// What the Guest knows to predict from.
#[derive(Debug, Clone, Default)]
pub struct Predictor {
    /// The newest feedback: its event, pose and wheels, and when it arrived.
    base: Option<Base>,
    /// Commands not yet in a feedback: event, when sent, the wheels asked.
    sent: VecDeque<(u64, Instant, WheelSpeeds)>,
    /// Whether this run is driven by commands (the watchdog applies).
    commanded: bool,
    /// Half the smoothed round trip, s.
    one_way_s: Option<f64>,
    /// What the display showed and when: the ghost's pose and the last
    /// reported pose, to be judged by the feedback describing that moment.
    shown: VecDeque<(Instant, Pose, Pose)>,
}

#[derive(Debug, Clone, Copy)]
struct Base {
    pose: Pose,
    wheels: WheelSpeeds,
    arrived: Instant,
}

impl Predictor {
    /// A run begins: nothing sent yet.
    pub fn start(&mut self) {
        self.sent.clear();
        self.shown.clear();
        self.commanded = false;
    }

    /// Feedback for `event` arrived at `now`.
    pub fn feedback(&mut self, event: u64, pose: Pose, wheels: WheelSpeeds, now: Instant) {
        self.base = Some(Base {
            pose,
            wheels,
            arrived: now,
        });
        self.sent.retain(|&(e, ..)| e > event);
    }

    /// Command `event` asking for `wheels` left at `now`.
    pub fn sent(&mut self, event: u64, wheels: WheelSpeeds, now: Instant) {
        if self.sent.len() == IN_FLIGHT {
            self.sent.pop_front();
        }
        self.sent.push_back((event, now, wheels));
        self.commanded = true;
    }

    /// A round trip took `ms`.
    pub fn round_trip(&mut self, ms: f64) {
        if !(ms.is_finite() && ms >= 0.0) {
            return;
        }
        let half = ms / 2e3;
        self.one_way_s = Some(match self.one_way_s {
            Some(s) => s + SMOOTHING * (half - s),
            None => half,
        });
    }

    /// The one-way delay the prediction assumes.
    pub fn one_way(&self) -> Duration {
        Duration::from_secs_f64(self.one_way_s.unwrap_or(0.0))
    }

    /// Remembers what the display shows at `now`: the ghost's pose and the
    /// last reported one.
    pub fn remember(&mut self, robot: &RobotModel, now: Instant) {
        let (Some(ghost), Some(base)) = (self.predict(robot, now), self.base) else {
            return;
        };
        if self.shown.len() == SHOWN_KEPT {
            self.shown.pop_front();
        }
        self.shown.push_back((now, ghost, base.pose));
    }

    /// Judges what was shown by feedback `pose` arriving at `now`, which
    /// tells where the robot was one one-way delay ago: how far the ghost
    /// shown then was from it, and how far the last reported pose was.
    pub fn judge(&mut self, pose: Pose, now: Instant) -> Option<(f64, f64)> {
        let moment = now.checked_sub(self.one_way()).unwrap_or(now);
        let mut then = None;
        while let Some(&(at, ..)) = self.shown.front() {
            if at > moment {
                break;
            }
            then = self.shown.pop_front();
        }
        then.map(|(_, ghost, reported)| {
            (
                ghost.point().distance(pose.point()),
                reported.point().distance(pose.point()),
            )
        })
    }

    /// Where the robot is at `now`, by the newest feedback carried forward;
    /// none before the first feedback.
    pub fn predict(&self, robot: &RobotModel, now: Instant) -> Option<Pose> {
        let moment = now;
        let base = self.base?;
        let one_way = self.one_way();
        // The feedback's pose held one one-way delay before it arrived.
        let from = base.arrived.checked_sub(one_way).unwrap_or(base.arrived);
        if moment <= from {
            return Some(base.pose);
        }
        let secs = |t: Instant| t.saturating_duration_since(from).as_secs_f64();
        // Each command takes effect one one-way delay after it left.
        let effects: Vec<(f64, WheelSpeeds)> = self
            .sent
            .iter()
            .map(|&(_, at, wheels)| (secs(at + one_way), robot.clamp(wheels)))
            .collect();
        let horizon = secs(moment);
        let mut pose = base.pose;
        let mut actual = base.wheels;
        let mut asked = base.wheels;
        let mut last_command: Option<f64> = self.commanded.then_some(0.0);
        let mut next = 0;
        let mut t = 0.0;
        while t < horizon {
            while next < effects.len() && effects[next].0 <= t {
                asked = effects[next].1;
                last_command = Some(effects[next].0);
                next += 1;
            }
            if last_command.is_some_and(|at| t - at > WATCHDOG.as_secs_f64()) {
                asked = WheelSpeeds::default();
            }
            let dt = STEP_S.min(horizon - t);
            (pose, actual) = robot.respond(pose, actual, asked, dt);
            t += dt;
        }
        Some(pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(v: f64) -> WheelSpeeds {
        WheelSpeeds {
            left_mm_s: v,
            right_mm_s: v,
        }
    }

    #[test]
    fn a_command_in_flight_moves_the_ghost_once_it_arrives() {
        let robot = RobotModel::khepera_ii();
        let t0 = Instant::now();
        let mut p = Predictor::default();
        p.round_trip(200.0);
        p.feedback(0, Pose::default(), straight(0.0), t0);
        p.sent(1, straight(100.0), t0);
        // Before the command reaches the robot nothing moves.
        let early = p.predict(&robot, t0 + Duration::from_millis(50)).unwrap();
        assert!(early.x_mm.abs() < 1e-9, "{early:?}");
        // 400 ms after the feedback's moment (one-way 100 ms before t0):
        // the command acted for 200 ms, minus the response's rise.
        let later = p.predict(&robot, t0 + Duration::from_millis(300)).unwrap();
        assert!((10.0..20.0).contains(&later.x_mm), "{later:?}");
    }

    #[test]
    fn the_watchdog_stops_the_ghost_too() {
        let robot = RobotModel::khepera_ii();
        let t0 = Instant::now();
        let mut p = Predictor::default();
        p.feedback(0, Pose::default(), straight(0.0), t0);
        p.sent(1, straight(100.0), t0);
        let a = p.predict(&robot, t0 + Duration::from_secs(1)).unwrap();
        let b = p.predict(&robot, t0 + Duration::from_secs(3)).unwrap();
        assert!(
            a.x_mm > 40.0 && (b.x_mm - a.x_mm).abs() < 1e-6,
            "{a:?} {b:?}"
        );
    }
}
