//! Where the robot is (thesis B.3): the wheels' odometry carries the pose
//! between camera frames, and each frame's sighting is folded in by an
//! extended Kalman filter. A sighting arrives after the frame was taken;
//! it is compared with the estimate of that moment and its correction
//! applied to the estimate of now.

use std::collections::VecDeque;

use nalgebra::{Matrix3, Vector3};

use crate::{Arena, Pose, RobotModel, mapped_reading, wrap_angle};

/// How far back sightings may reach, s: a frame is grabbed, processed and
/// handed over well within this.
const HISTORY_S: f64 = 0.5;
/// A sighting this unlikely (squared Mahalanobis distance; χ² with 3
/// degrees of freedom is above it once in 10⁵) is not folded in…
const GATE: f64 = 25.0;
/// …unless this many come in a row: then the robot was moved (or the
/// estimate lost), and the camera is believed outright.
const REJECTS_BEFORE_RESET: u32 = 3;
/// How long a reset counts in `overruled`, s.
const OVERRULED_S: f64 = 3.0;

/// A proximity reading is compared with the map only above this (the
/// sensor's noise floor is about 10)…
const RANGE_MIN_READING: f64 = 40.0;
/// …and only where the map puts a surface within this share of the
/// sensor's range, where a reading changes fast with distance.
const RANGE_SHARE: f64 = 0.8;
/// A reading this many standard deviations from the map's is something
/// the map does not show (a box, a hand), not a correction.
const RANGE_GATE_SIGMAS: f64 = 3.0;
/// Readings are folded in only once a wheel has rolled this far, mm,
/// since the last: a robot at rest reads the same surfaces again, whose
/// errors do not average out, and its estimate must not wander.
const RANGE_AFTER_MM: f64 = 1.0;

/// How much each source is trusted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uncertainty {
    /// Standard deviation of a wheel's travel per √mm it travels (slip).
    pub wheel_slip: f64,
    /// Distance between the wheels, mm: what turns a wheel's error into
    /// the heading's.
    pub wheel_base_mm: f64,
    /// Standard deviation of a sighting's position, mm.
    pub camera_mm: f64,
    /// Standard deviation of a sighting's heading, rad.
    pub camera_rad: f64,
}

impl Uncertainty {
    /// `robot`'s odometry as its model measured it, seen by a camera
    /// locating its marker within about a millimetre.
    pub fn for_robot(robot: &RobotModel) -> Uncertainty {
        Uncertainty {
            wheel_slip: robot.wheel_slip,
            wheel_base_mm: robot.wheel_base_mm,
            camera_mm: 1.0,
            camera_rad: 0.03,
        }
    }
}

/// What became of a sighting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fold {
    /// Folded into the estimate.
    Folded,
    /// Too far from the estimate to believe, for now.
    Rejected,
    /// The estimate was replaced by it (the first sighting, or after
    /// several in a row disagreed).
    Reset,
    /// Older than the history kept.
    TooOld,
}

/// The robot's pose, estimated from odometry and sightings.
#[derive(Debug, Clone)]
pub struct Localiser {
    state: Vector3<f64>,
    covariance: Matrix3<f64>,
    uncertainty: Uncertainty,
    /// The last odometry reading, to take the next one's difference from.
    odometry: Option<Pose>,
    /// Recent estimates, oldest first: (time, state).
    history: VecDeque<(f64, Vector3<f64>)>,
    last_sighting: Option<f64>,
    rejects: u32,
    /// Each reset after the first sighting within `OVERRULED_S` of the
    /// newest: when, and how far it moved and turned the estimate.
    overruled: VecDeque<(f64, f64, f64)>,
    /// Wheel travel since the proximity readings were last folded in, mm.
    rolled_mm: f64,
}

impl Localiser {
    /// Believes the robot is at `start`, give or take 50 mm and 0.5 rad,
    /// until the camera says otherwise.
    pub fn new(start: Pose, uncertainty: Uncertainty) -> Localiser {
        Localiser {
            state: Vector3::new(start.x_mm, start.y_mm, start.theta_rad),
            covariance: Matrix3::from_diagonal(&Vector3::new(2500.0, 2500.0, 0.25)),
            uncertainty,
            odometry: None,
            history: VecDeque::new(),
            last_sighting: None,
            rejects: 0,
            overruled: VecDeque::new(),
            rolled_mm: 0.0,
        }
    }

    /// Knows the robot is at `start`, as when it was put there by hand
    /// (within a millimetre and a degree or so), with no camera to say.
    pub fn placed(start: Pose, uncertainty: Uncertainty) -> Localiser {
        Localiser {
            covariance: Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 3e-4)),
            ..Localiser::new(start, uncertainty)
        }
    }

    pub fn pose(&self) -> Pose {
        Pose {
            x_mm: self.state.x,
            y_mm: self.state.y,
            theta_rad: self.state.z,
        }
    }

    /// Standard deviation of the position along its least certain
    /// direction, mm: how far the robot may be from the estimate.
    pub fn position_sd_mm(&self) -> f64 {
        let (a, b, c) = (
            self.covariance[(0, 0)],
            self.covariance[(0, 1)],
            self.covariance[(1, 1)],
        );
        let largest = (a + c) / 2.0 + (((a - c) / 2.0).powi(2) + b * b).sqrt();
        largest.max(0.0).sqrt()
    }

    /// How far, mm, and how much, rad, the camera moved and turned the
    /// estimate in its resets of the last three seconds up to the newest:
    /// odometry that keeps disagreeing with the camera adds up here (wheels
    /// spinning on the spot, a robot carried away, odometry that lies),
    /// where slip and jitter are folded in and add nothing.
    pub fn overruled(&self) -> (f64, f64) {
        self.overruled
            .iter()
            .fold((0.0, 0.0), |(mm, rad), &(_, moved, turned)| {
                (mm + moved, rad + turned)
            })
    }

    /// Seconds from the last sighting folded in to `now_s`; None before any.
    pub fn since_sighting(&self, now_s: f64) -> Option<f64> {
        self.last_sighting.map(|t| now_s - t)
    }

    /// Moves the estimate as the robot moved between the previous
    /// odometry reading and `odometry`, read at `now_s`.
    pub fn odometry(&mut self, now_s: f64, odometry: Pose) {
        let finite = odometry.x_mm.is_finite()
            && odometry.y_mm.is_finite()
            && odometry.theta_rad.is_finite();
        if let (Some(previous), true) = (self.odometry, finite) {
            // The motion in the robot's own frame, carried onto the estimate.
            let (s, c) = previous.theta_rad.sin_cos();
            let (dx, dy) = (odometry.x_mm - previous.x_mm, odometry.y_mm - previous.y_mm);
            let forward = c * dx + s * dy;
            let left = -s * dx + c * dy;
            let turn = wrap_angle(odometry.theta_rad - previous.theta_rad);
            let (s, c) = self.state.z.sin_cos();
            self.state.x += c * forward - s * left;
            self.state.y += s * forward + c * left;
            self.state.z = wrap_angle(self.state.z + turn);
            // Jacobian of the motion with respect to the heading.
            let f = Matrix3::new(
                1.0,
                0.0,
                -s * forward - c * left,
                0.0,
                1.0,
                c * forward - s * left,
                0.0,
                0.0,
                1.0,
            );
            // Each wheel errs by its slip over its own travel; the two
            // errors move the pose along the heading and turn it.
            let b = self.uncertainty.wheel_base_mm.max(1.0);
            let (left_mm, right_mm) = (forward - turn * b / 2.0, forward + turn * b / 2.0);
            self.rolled_mm += left_mm.abs().max(right_mm.abs());
            let k2 = self.uncertainty.wheel_slip.powi(2);
            let wheels = nalgebra::Matrix2::new(k2 * left_mm.abs(), 0.0, 0.0, k2 * right_mm.abs());
            let g = nalgebra::Matrix3x2::new(c / 2.0, c / 2.0, s / 2.0, s / 2.0, -1.0 / b, 1.0 / b);
            self.covariance = f * self.covariance * f.transpose() + g * wheels * g.transpose();
        }
        if finite {
            self.odometry = Some(odometry);
        }
        self.history.push_back((now_s, self.state));
        while self
            .history
            .front()
            .is_some_and(|&(t, _)| t < now_s - HISTORY_S)
        {
            self.history.pop_front();
        }
    }

    /// Folds in the proximity sensors' readings against the map (thesis
    /// B.3's odometry has nothing else when no camera watches): each sensor
    /// whose ray meets a mapped surface near enough is a measurement of
    /// the pose, as the simulator and the IR response make readings. Returns
    /// how many readings were folded in.
    pub fn ranges(&mut self, robot: &RobotModel, arena: &Arena, proximity: &[u16]) -> usize {
        if self.rolled_mm < RANGE_AFTER_MM {
            return 0;
        }
        self.rolled_mm = 0.0;
        let mut folded = 0;
        for (mount, &reading) in robot.sensors.iter().zip(proximity) {
            let reading = f64::from(reading);
            let expected = |state: &Vector3<f64>| {
                let pose = Pose {
                    x_mm: state.x,
                    y_mm: state.y,
                    theta_rad: state.z,
                };
                mapped_reading(arena, pose, mount)
            };
            let (h, distance) = expected(&self.state);
            if reading < RANGE_MIN_READING || distance > RANGE_SHARE * robot.sensor_range_mm {
                continue;
            }
            // The reading's slope against the pose, by small steps.
            let steps = [0.5, 0.5, 0.005];
            let mut jacobian = nalgebra::RowVector3::zeros();
            for (i, step) in steps.into_iter().enumerate() {
                let mut moved = self.state;
                moved[i] += step;
                jacobian[i] = (expected(&moved).0 - h) / step;
            }
            // The response's noise (a few per cent) and its model's error.
            let r = (0.05 * h + 5.0).powi(2);
            let s = (jacobian * self.covariance * jacobian.transpose())[0] + r;
            let innovation = reading - h;
            if innovation * innovation > RANGE_GATE_SIGMAS.powi(2) * s {
                continue;
            }
            let gain = self.covariance * jacobian.transpose() / s;
            self.state += gain * innovation;
            self.state.z = wrap_angle(self.state.z);
            self.covariance = (Matrix3::identity() - gain * jacobian) * self.covariance;
            folded += 1;
        }
        folded
    }

    /// Folds in the camera's sighting of the robot at `seen`, in a frame
    /// taken at `taken_s`.
    pub fn sighting(&mut self, taken_s: f64, seen: Pose) -> Fold {
        if !(seen.x_mm.is_finite() && seen.y_mm.is_finite() && seen.theta_rad.is_finite()) {
            return Fold::Rejected;
        }
        let z = Vector3::new(seen.x_mm, seen.y_mm, seen.theta_rad);
        if self.last_sighting.is_none() {
            return self.reset(taken_s, z);
        }
        // The estimate when the frame was taken.
        let then = match self.history.iter().rev().find(|&&(t, _)| t <= taken_s) {
            Some(&(_, state)) => state,
            None if self.history.is_empty() => self.state,
            None => return Fold::TooOld,
        };
        let mut innovation = z - then;
        innovation.z = wrap_angle(innovation.z);
        let u = &self.uncertainty;
        let r = Matrix3::from_diagonal(&Vector3::new(
            u.camera_mm.powi(2),
            u.camera_mm.powi(2),
            u.camera_rad.powi(2),
        ));
        let s = self.covariance + r;
        let Some(s_inv) = s.try_inverse() else {
            return self.reset(taken_s, z);
        };
        if (innovation.transpose() * s_inv * innovation)[0] > GATE {
            self.rejects += 1;
            if self.rejects >= REJECTS_BEFORE_RESET {
                return self.reset(taken_s, z);
            }
            return Fold::Rejected;
        }
        self.rejects = 0;
        let gain = self.covariance * s_inv;
        let correction = gain * innovation;
        self.state += correction;
        self.state.z = wrap_angle(self.state.z);
        for (t, state) in self.history.iter_mut() {
            if *t >= taken_s {
                *state += correction;
            }
        }
        self.covariance = (Matrix3::identity() - gain) * self.covariance;
        self.last_sighting = Some(taken_s);
        Fold::Folded
    }

    /// Believes the sighting outright: the robot is where the camera saw
    /// it, moved on by the odometry since.
    fn reset(&mut self, taken_s: f64, z: Vector3<f64>) -> Fold {
        let then = self
            .history
            .iter()
            .rev()
            .find(|&&(t, _)| t <= taken_s)
            .map_or(self.state, |&(_, s)| s);
        // What odometry added since the frame, kept on top of the sighting.
        let since = self.state - then;
        let before = self.state;
        self.state = z;
        self.state.x += since.x;
        self.state.y += since.y;
        self.state.z = wrap_angle(z.z + since.z);
        if self.last_sighting.is_some() {
            let moved = (self.state.x - before.x).hypot(self.state.y - before.y);
            let turned = wrap_angle(self.state.z - before.z).abs();
            self.overruled.push_back((taken_s, moved, turned));
        }
        while self
            .overruled
            .front()
            .is_some_and(|&(t, _, _)| t < taken_s - OVERRULED_S)
        {
            self.overruled.pop_front();
        }
        let u = &self.uncertainty;
        self.covariance = Matrix3::from_diagonal(&Vector3::new(
            u.camera_mm.powi(2) * 4.0,
            u.camera_mm.powi(2) * 4.0,
            u.camera_rad.powi(2) * 4.0,
        ));
        self.history.clear();
        self.rejects = 0;
        self.last_sighting = Some(taken_s);
        Fold::Reset
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::WheelSpeeds;
    use proptest::prelude::*;

    fn uncertainty() -> Uncertainty {
        Uncertainty::for_robot(&RobotModel::khepera_ii())
    }

    fn pose(x_mm: f64, y_mm: f64, theta_rad: f64) -> Pose {
        Pose {
            x_mm,
            y_mm,
            theta_rad,
        }
    }

    proptest! {
        /// Odometry alone moves the estimate by the robot's own motion,
        /// whatever frame the odometry counts in.
        #[test]
        fn odometry_alone_carries_the_motion(
            start in (0.0f64..800.0, 0.0f64..600.0, -3.0f64..3.0),
            origin in (-500.0f64..500.0, -500.0f64..500.0, -3.0f64..3.0),
            drives in prop::collection::vec((-300.0f64..300.0, -300.0f64..300.0), 1..40),
        ) {
            let start = pose(start.0, start.1, start.2);
            let mut truth = start;
            let mut odometry = pose(origin.0, origin.1, origin.2);
            let mut loc = Localiser::new(start, uncertainty());
            loc.odometry(0.0, odometry);
            for (i, &(l, r)) in drives.iter().enumerate() {
                let wheels = WheelSpeeds { left_mm_s: l, right_mm_s: r };
                truth = truth.advance(wheels, 53.0, 0.05);
                odometry = odometry.advance(wheels, 53.0, 0.05);
                loc.odometry(0.05 * (i + 1) as f64, odometry);
            }
            let p = loc.pose();
            prop_assert!(p.point().distance(truth.point()) < 1e-6, "{p:?} vs {truth:?}");
            prop_assert!(wrap_angle(p.theta_rad - truth.theta_rad).abs() < 1e-9);
        }

        /// Sightings, however noisy or late, keep the estimate finite and
        /// closer to the truth than drifting odometry alone.
        #[test]
        fn sightings_beat_drifting_odometry(seed in any::<u64>(), delay_ticks in 0usize..8) {
            let mut rng = seed | 1;
            let mut noise = move || {
                rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17;
                (rng % 20001) as f64 / 10000.0 - 1.0
            };
            let start = pose(100.0, 100.0, 0.3);
            let (mut truth, mut odometry) = (start, start);
            // Odometry this biased measures as slipping about 0.1 mm per √mm.
            let biased = Uncertainty { wheel_slip: 0.1, ..uncertainty() };
            let mut fused = Localiser::new(start, biased);
            let mut blind = Localiser::new(start, biased);
            fused.sighting(0.0, start);
            let mut frames = VecDeque::new();
            let (mut err_fused, mut err_blind) = (0.0f64, 0.0f64);
            for k in 0..600 {
                let t = k as f64 * 0.01;
                let wheels = WheelSpeeds { left_mm_s: 150.0 + 60.0 * (t * 0.7).sin(), right_mm_s: 150.0 };
                truth = truth.advance(wheels, 53.0, 0.01);
                // Odometry counts slipping wheels: 3 % off, biased.
                let slipping = WheelSpeeds { left_mm_s: wheels.left_mm_s * 1.03, right_mm_s: wheels.right_mm_s };
                odometry = odometry.advance(slipping, 53.0, 0.01);
                fused.odometry(t, odometry);
                blind.odometry(t, odometry);
                if k % 7 == 0 {
                    let seen = pose(truth.x_mm + noise(), truth.y_mm + noise(), truth.theta_rad + 0.02 * noise());
                    frames.push_back((t, seen));
                }
                // Frames arrive `delay_ticks` after they were taken.
                while frames.front().is_some_and(|&(taken, _)| taken <= t - delay_ticks as f64 * 0.01) {
                    let (taken, seen) = frames.pop_front().unwrap();
                    fused.sighting(taken, seen);
                }
                let p = fused.pose();
                prop_assert!(p.x_mm.is_finite() && p.y_mm.is_finite() && p.theta_rad.is_finite());
                // Slip, noise and lateness are folded in: the camera never
                // has to overrule the odometry.
                prop_assert_eq!(fused.overruled(), (0.0, 0.0));
                err_fused = err_fused.max(p.point().distance(truth.point()));
                err_blind = err_blind.max(blind.pose().point().distance(truth.point()));
            }
            prop_assert!(err_fused < 4.0, "fused {err_fused:.2} mm");
            prop_assert!(err_blind > 3.0 * err_fused, "blind {err_blind:.2} mm, fused {err_fused:.2} mm");
        }
    }

    proptest! {
        /// Wheels that spin while the robot stays (stuck, held, or
        /// odometry that lies): the camera keeps resetting the estimate,
        /// and what it overruled adds up past 5 cm within three seconds,
        /// however fast the wheels go (from a crawl) and the frames come.
        #[test]
        fn spinning_wheels_add_up_to_overruled(
            speed in 40.0f64..400.0,
            frame_ticks in 5usize..10,
            late_ticks in 0usize..5,
        ) {
            let held = pose(300.0, 200.0, 0.4);
            let mut odometry = held;
            let mut loc = Localiser::new(held, uncertainty());
            loc.sighting(0.0, held);
            let wheels = WheelSpeeds { left_mm_s: speed, right_mm_s: speed };
            let mut contradicted = false;
            for k in 1..=300 {
                let t = k as f64 * 0.01;
                odometry = odometry.advance(wheels, 53.0, 0.01);
                loc.odometry(t, odometry);
                if k % frame_ticks == 0 && k > late_ticks {
                    loc.sighting(t - late_ticks as f64 * 0.01, held);
                }
                contradicted |= loc.overruled().0 > 50.0;
            }
            prop_assert!(contradicted, "overruled {:?}", loc.overruled());
        }
    }

    proptest! {
        /// Down the corridor with odometry whose heading drifts, the
        /// proximity sensors against the map keep the estimate near the
        /// truth, far nearer than odometry alone, and a box the map does
        /// not show is not taken for a wall.
        #[test]
        fn the_sensors_against_the_map_hold_the_estimate(seed in any::<u64>(), bias in 0.005f64..0.02) {
            let robot = RobotModel::khepera_ii();
            let arena = Arena::named("corridor").unwrap();
            let mut unmapped = arena.clone();
            unmapped.obstacles.push(crate::Obstacle {
                shape: "rect:600,250,40,30".parse().unwrap(),
                material: crate::Material::default(),
            });
            let mut rng = seed | 1;
            let mut noise = move || {
                rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17;
                (rng % 20001) as f64 / 10000.0 - 1.0
            };
            let start = arena.start;
            let (mut truth, mut odometry) = (start, start);
            let mut ranged = Localiser::placed(start, uncertainty());
            let mut blind = Localiser::placed(start, uncertainty());
            let (mut err_ranged, mut err_blind) = (0.0f64, 0.0f64);
            for k in 0..400 {
                let t = k as f64 * 0.01;
                let heading = wrap_angle(0.0 - truth.theta_rad);
                let wheels = WheelSpeeds { left_mm_s: 180.0 - 40.0 * heading, right_mm_s: 180.0 + 40.0 * heading };
                truth = truth.advance(wheels, robot.wheel_base_mm, 0.01);
                let slipping = WheelSpeeds { left_mm_s: wheels.left_mm_s * (1.0 + bias), ..wheels };
                odometry = odometry.advance(slipping, robot.wheel_base_mm, 0.01);
                let proximity: Vec<u16> = robot.sensors.iter().map(|m| {
                    let (clean, distance_mm) = mapped_reading(&unmapped, truth, m);
                    let v = if distance_mm <= robot.sensor_range_mm {
                        clean * (1.0 + 0.03 * noise())
                    } else { 5.0 };
                    v.round().clamp(0.0, 1023.0) as u16
                }).collect();
                ranged.odometry(t, odometry);
                ranged.ranges(&robot, &arena, &proximity);
                blind.odometry(t, odometry);
                let p = ranged.pose();
                prop_assert!(p.x_mm.is_finite() && p.y_mm.is_finite() && p.theta_rad.is_finite());
                err_ranged = err_ranged.max((p.y_mm - truth.y_mm).abs());
                err_blind = err_blind.max((blind.pose().y_mm - truth.y_mm).abs());
            }
            prop_assert!(err_ranged < 6.0, "across the corridor: ranged {err_ranged:.1} mm, blind {err_blind:.1} mm");
            prop_assert!(err_blind > 2.0 * err_ranged, "ranged {err_ranged:.1} mm, blind {err_blind:.1} mm");
        }
    }

    /// A robot at rest reads the same walls again and again: its estimate
    /// stays where it is.
    #[test]
    fn a_still_robot_is_not_moved_by_its_sensors() {
        let robot = RobotModel::khepera_ii();
        let arena = Arena::named("corridor").unwrap();
        let start = arena.start;
        let mut loc = Localiser::placed(start, uncertainty());
        for k in 0..200u16 {
            loc.odometry(f64::from(k) * 0.01, start);
            // Readings off by a few per cent either way, as a sensor's are.
            let proximity: Vec<u16> = robot
                .sensors
                .iter()
                .map(|m| {
                    let v =
                        mapped_reading(&arena, start, m).0 * if k % 2 == 0 { 1.04 } else { 0.97 };
                    v.min(1023.0) as u16
                })
                .collect();
            assert_eq!(loc.ranges(&robot, &arena, &proximity), 0);
        }
        assert_eq!(loc.pose(), start);
    }

    #[test]
    fn the_first_sighting_and_a_moved_robot_reset_the_estimate() {
        let mut loc = Localiser::new(pose(0.0, 0.0, 0.0), uncertainty());
        loc.odometry(0.0, pose(0.0, 0.0, 0.0));
        assert_eq!(loc.since_sighting(1.0), None);
        assert_eq!(loc.sighting(0.0, pose(300.0, 200.0, 1.0)), Fold::Reset);
        assert!(loc.pose().point().distance(pose(300.0, 200.0, 0.0).point()) < 1e-9);
        assert_eq!(loc.since_sighting(0.5), Some(0.5));
        // Someone carries the robot 200 mm: the first sightings there are
        // doubted, then believed.
        let far = pose(500.0, 200.0, 1.0);
        for t in 1..=2 {
            loc.odometry(f64::from(t) * 0.1, pose(0.0, 0.0, 0.0));
            assert_eq!(loc.sighting(f64::from(t) * 0.1, far), Fold::Rejected);
        }
        loc.odometry(0.3, pose(0.0, 0.0, 0.0));
        assert_eq!(loc.sighting(0.3, far), Fold::Reset);
        assert!(loc.pose().point().distance(far.point()) < 1e-9);
        assert_eq!(loc.sighting(0.3, pose(f64::NAN, 0.0, 0.0)), Fold::Rejected);
        loc.odometry(5.0, pose(0.0, 0.0, 0.0));
        assert_eq!(loc.sighting(1.0, far), Fold::TooOld);
    }
}
