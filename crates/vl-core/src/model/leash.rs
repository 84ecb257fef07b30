//! The leash: a drive command that carries its own end.
//!
//! A Khepera keeps whatever speed it was last told, so a Host that stalls
//! (a kernel stall, a swap storm, a debugger) would leave it driving. Its
//! position controller does not: told a target (`C`), each wheel follows a
//! trapezoid — speeding up by the profile's acceleration (`J`) to its top
//! speed, then slowing down by the same acceleration to stop at the
//! target by itself. So every motion the Host sends is a [`Leash`]: each
//! wheel's top speed and how far it may turn, no further than the robot can
//! go and still stop clear of everything (the safety layer checks exactly
//! this motion), and just long enough that, extended every control period,
//! the robot never slows for it. A Host that stops extending it leaves a
//! robot that stops within its braking distance.
//!
//! [`WheelMove`] is that trapezoid, the one law the emulated firmware, the
//! simulated robot and the safety layer's check all move a wheel by.

use crate::{RobotModel, SpeedResponse, WheelSpeeds};

/// One wheel's move under the position controller (`C` with the profile
/// `J` set): to `target_mm` of travel, no faster than `top_mm_s`,
/// changing speed by `accel_mm_s2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelMove {
    pub target_mm: f64,
    pub top_mm_s: f64,
    pub accel_mm_s2: f64,
}

/// A wheel's position controller: a reference that moves along the
/// trapezoid of the move in force, and the wheel asked to follow it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PositionControl {
    /// Where the reference is, mm of travel, and how fast it goes, mm/s.
    pub reference_mm: f64,
    pub speed_mm_s: f64,
}

/// Nearer than this to its target, mm, a reference slow enough to stop
/// within a step is on it: finer than an encoder pulse.
const ON_TARGET_MM: f64 = 0.01;

impl PositionControl {
    /// The controller taking over a wheel at `at_mm` going `speed_mm_s`.
    pub fn taking_over(at_mm: f64, speed_mm_s: f64) -> PositionControl {
        PositionControl {
            reference_mm: at_mm,
            speed_mm_s,
        }
    }

    /// Moves the reference `dt_s` on along `m` — toward the top speed, or
    /// the fastest from which it still stops on the target, whichever is
    /// lower, by at most the acceleration — and returns the speed the
    /// wheel at `wheel_mm` is asked for: the reference's, led by the
    /// wheels' lag (`response`), and a critically damped pull toward it.
    /// A target too near to stop at is passed and come back to, as a
    /// trapezoid does; a leash never sets one.
    pub fn step(
        &mut self,
        m: &WheelMove,
        wheel_mm: f64,
        response: &SpeedResponse,
        dt_s: f64,
    ) -> f64 {
        let remaining = m.target_mm - self.reference_mm;
        let change = m.accel_mm_s2.max(0.0) * dt_s;
        let was = self.speed_mm_s;
        if remaining.abs() <= ON_TARGET_MM && was.abs() <= change {
            self.speed_mm_s = 0.0;
            self.reference_mm = m.target_mm;
        } else {
            let stoppable = (2.0 * m.accel_mm_s2.max(0.0) * remaining.abs())
                .sqrt()
                .min(remaining.abs() / dt_s.max(1e-9));
            let want = remaining.signum() * m.top_mm_s.abs().min(stoppable);
            self.speed_mm_s += (want - was).clamp(-change, change);
            self.reference_mm += self.speed_mm_s * dt_s;
        }
        let lag = response.time_constant_s.max(dt_s);
        let asked = self.speed_mm_s
            + lag * (self.speed_mm_s - was) / dt_s.max(1e-9)
            + (self.reference_mm - wheel_mm) / (4.0 * lag);
        if asked.is_finite() && self.reference_mm.is_finite() {
            asked
        } else {
            *self = PositionControl::taking_over(wheel_mm, 0.0);
            0.0
        }
    }
}

/// A drive command with its own end, in the firmware's units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Leash {
    /// Each wheel's top speed, pulses per 10 ms, signed by its direction.
    pub top: [i64; 2],
    /// How far each wheel may turn from its count when the robot was last
    /// read, pulses, signed.
    pub reach: [i64; 2],
}

/// How far a speed going from `from` toward `to` by `accel` moves in
/// `secs`, mm, and where it ends, mm/s.
fn ramp(from: f64, to: f64, accel: f64, secs: f64) -> (f64, f64) {
    let reach_s = (to - from).abs() / accel;
    if reach_s >= secs {
        let end = from + (to - from).signum() * accel * secs;
        ((from + end) / 2.0 * secs, end)
    } else {
        ((from + to) / 2.0 * reach_s + to * (secs - reach_s), to)
    }
}

impl Leash {
    /// Stand still: stopped at once by the speed controller (`D,0,0`),
    /// which brakes harder than the position controller's profile.
    pub const STOP: Leash = Leash {
        top: [0; 2],
        reach: [0; 2],
    };

    pub fn is_stop(&self) -> bool {
        self.top == [0; 2]
    }

    /// The leash for `wheels` (top speeds), to last `hold_s` before the
    /// next one extends it, for wheels going at `now` that it reaches only
    /// `arrives_s` from their reading. Each wheel may go as far as its
    /// controller takes it in that time and the hold (speeding up or
    /// slowing down toward its top by the profile's acceleration), then as
    /// far as it needs to stop from there: so a wheel is never asked to
    /// stop sooner than it can, and one told to turn back first stops
    /// (a target is a place, and the profile's top speed holds either way:
    /// one past the stopping point would speed the wheel up the wrong way,
    /// one short of it brakes the wheel hardest).
    pub fn new(
        robot: &RobotModel,
        wheels: WheelSpeeds,
        hold_s: f64,
        now: WheelSpeeds,
        arrives_s: f64,
    ) -> Leash {
        let wheels = robot.clamp(wheels);
        let now = robot.clamp(now);
        let accel = robot.profile_accel_mm_s2();
        let top = [
            robot.pulses_per_period(wheels.left_mm_s),
            robot.pulses_per_period(wheels.right_mm_s),
        ];
        if top == [0; 2] {
            return Leash::STOP;
        }
        let mut reach = [0; 2];
        for (i, speed) in [now.left_mm_s, now.right_mm_s].into_iter().enumerate() {
            let v = robot.speed_mm_s(top[i]);
            let coast = speed * arrives_s.max(0.0);
            let (held, end) = ramp(speed, v, accel, hold_s.max(0.0));
            let stop = coast + held + end * end.abs() / (2.0 * accel);
            // The controller's reference may be off the wheel by as far as
            // the wheel lags it: the target is moved that much the way the
            // wheel is told to go (or, told to stand, back from where it
            // stops), so the profile never slows a wheel going its way for
            // it, and brakes one turning back as hard as it can (it stops
            // past the target, and comes back: the way it is told).
            let unsure =
                speed.abs().max(end.abs()) * robot.response.time_constant_s + robot.mm_per_pulse;
            let way = if v != 0.0 {
                v.signum()
            } else if end != 0.0 {
                -end.signum()
            } else {
                0.0
            };
            let pulses = ((stop + way * unsure) / robot.mm_per_pulse).round();
            reach[i] = pulses.clamp(-f64::from(i32::MAX), f64::from(i32::MAX)) as i64;
        }
        Leash { top, reach }
    }

    /// The top speeds, mm/s.
    pub fn wheels(&self, robot: &RobotModel) -> WheelSpeeds {
        WheelSpeeds {
            left_mm_s: robot.speed_mm_s(self.top[0]),
            right_mm_s: robot.speed_mm_s(self.top[1]),
        }
    }

    /// Each wheel's move, its travel at the reading being `from_mm`.
    pub fn moves(&self, robot: &RobotModel, from_mm: [f64; 2]) -> [WheelMove; 2] {
        let accel_mm_s2 = robot.profile_accel_mm_s2();
        [0, 1].map(|i| WheelMove {
            target_mm: from_mm[i] + self.reach[i] as f64 * robot.mm_per_pulse,
            top_mm_s: robot.speed_mm_s(self.top[i]).abs(),
            accel_mm_s2,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A wheel under `m` from `speed` at 0 mm, through the Khepera's
    /// response: where it ends, and the furthest it went.
    fn ride(m: WheelMove, speed: f64) -> (f64, f64) {
        let response = SpeedResponse::default();
        let mut control = PositionControl::taking_over(0.0, speed);
        let (mut wheel, mut at, mut furthest) = (speed, 0.0, 0.0f64);
        for _ in 0..7500 {
            let asked = control.step(&m, at, &response, 0.002);
            let next = response.step(wheel, asked, 0.002);
            at += (wheel + next) / 2.0 * 0.002;
            wheel = next;
            furthest = furthest.max(at);
        }
        (at, furthest)
    }

    #[test]
    fn a_move_speeds_up_holds_and_stops_on_target() {
        let m = WheelMove {
            target_mm: 300.0,
            top_mm_s: 200.0,
            accel_mm_s2: 800.0,
        };
        let mut control = PositionControl::default();
        let response = SpeedResponse::default();
        let mut top = 0.0f64;
        for step in 0..400 {
            control.step(&m, control.reference_mm, &response, 0.01);
            top = top.max(control.speed_mm_s);
            if step == 9 {
                // 0.1 s at 800 mm/s²: 80 mm/s.
                assert!((control.speed_mm_s - 80.0).abs() < 1e-6, "{control:?}");
            }
        }
        assert!((top - 200.0).abs() < 1e-9);
        assert_eq!(control.reference_mm, 300.0);
        assert_eq!(control.speed_mm_s, 0.0);
        let (end, furthest) = ride(m, 0.0);
        assert!(
            (end - 300.0).abs() < 0.1 && furthest < 300.5,
            "{end} {furthest}"
        );
    }

    #[test]
    fn the_leash_reaches_past_the_hold_by_the_braking_distance() {
        let robot = RobotModel::khepera_ii();
        let a = robot.profile_accel_mm_s2();
        assert!((a - 255.0 * 0.08 / 256.0 / 1e-4).abs() < 1e-9, "{a}");
        let ahead = WheelSpeeds {
            left_mm_s: 400.0,
            right_mm_s: -400.0,
        };
        let leash = Leash::new(&robot, ahead, 0.1, ahead, 0.0);
        assert_eq!(leash.top, [50, -50]);
        let mm = leash.reach[0] as f64 * robot.mm_per_pulse;
        let want = 400.0 * 0.1 + 400.0 * 400.0 / (2.0 * a) + 400.0 * 0.03;
        assert!(mm >= want && mm < want + 0.2, "{mm} vs {want}");
        assert_eq!(leash.reach[1], -leash.reach[0]);
        // Told to turn back at full speed, the wheels first stop: within
        // the hold they only slow down, and the leash ends where they stop.
        let back = Leash::new(
            &robot,
            ahead,
            0.1,
            WheelSpeeds {
                left_mm_s: -400.0,
                right_mm_s: 400.0,
            },
            0.0,
        );
        let end = -400.0 + a * 0.1;
        let stop_mm = (-400.0 + end) / 2.0 * 0.1 - end * end / (2.0 * a);
        let short = back.reach[0] as f64 * robot.mm_per_pulse - stop_mm;
        assert!(
            (short - 400.0 * 0.03).abs() < 0.2,
            "{back:?}: {short} mm short of {stop_mm}"
        );
        assert!(Leash::new(&robot, WheelSpeeds::default(), 0.1, ahead, 0.0).is_stop());
        let nonsense = WheelSpeeds {
            left_mm_s: f64::NAN,
            right_mm_s: 1e300,
        };
        assert!(Leash::new(&robot, nonsense, 0.1, nonsense, 0.0).is_stop());
    }

    proptest! {
        /// From any speed the profile could have reached it by, a wheel
        /// stops on its target, passing it by at most 2 mm per m/s (its lag).
        #[test]
        fn a_wheel_stops_on_a_target_it_could_stop_at(
            target in 0.5f64..1000.0,
            top in 100.0f64..1016.0,
            share in 0.0f64..1.0,
        ) {
            let accel = RobotModel::khepera_ii().profile_accel_mm_s2();
            let m = WheelMove { target_mm: target, top_mm_s: top, accel_mm_s2: accel };
            let speed = share * top.min((2.0 * accel * target).sqrt());
            let (end, furthest) = ride(m, speed);
            prop_assert!(furthest <= target + 0.5 + 0.002 * top, "{furthest} past {target}");
            prop_assert!((end - target).abs() < 0.1, "stopped at {end} for {target}");
        }

        /// Held at its top speed for `hold_s`, then left alone, a leashed
        /// wheel keeps its speed all the hold and stops within its reach.
        #[test]
        fn a_leash_lets_the_wheel_run_then_stops_it(v in -1016.0f64..1016.0, hold in 0.01f64..0.3) {
            let robot = RobotModel::khepera_ii();
            let top = robot.speed_mm_s(robot.pulses_per_period(v));
            let going = WheelSpeeds { left_mm_s: top, right_mm_s: top };
            let leash = Leash::new(&robot, going, hold, going, 0.0);
            let m = leash.moves(&robot, [0.0; 2])[0];
            let mut control = PositionControl::taking_over(0.0, top);
            let (mut wheel, mut at) = (top, 0.0);
            let reach = leash.reach[0] as f64 * robot.mm_per_pulse;
            for step in 0..2500 {
                let asked = control.step(&m, at, &robot.response, 0.002);
                if (step as f64) < hold / 0.002 {
                    prop_assert!((control.speed_mm_s - top).abs() < 1e-9, "slowed to {:?} of {top}", control);
                }
                let next = robot.response.step(wheel, asked, 0.002);
                at += (wheel + next) / 2.0 * 0.002;
                wheel = next;
                prop_assert!(at.abs() <= reach.abs() + 0.5 + 0.002 * top.abs(), "{at} past {reach}");
            }
            prop_assert!(wheel.abs() < 1e-6 && (at - reach).abs() < 0.1, "{wheel} mm/s at {at} of {reach}");
        }
    }
}
