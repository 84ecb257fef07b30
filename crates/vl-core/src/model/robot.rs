//! The robot model: geometry, limits and sensor layout the Guest needs to
//! draw and predict the robot, and the differential-drive kinematics both
//! the simulator and the Guest's predictor use.

use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::Named;
use crate::syntax::{SyntaxError, parse_numbers};

/// A planar pose in the arena frame: mm, origin at the arena's bottom-left
/// corner, x right, y up, θ counter-clockwise from +x.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
pub struct Pose {
    pub x_mm: f64,
    pub y_mm: f64,
    pub theta_rad: f64,
}

/// A point in the arena frame, in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
pub struct Point {
    pub x_mm: f64,
    pub y_mm: f64,
}

/// Wheel surface speeds, mm/s, positive forward.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
pub struct WheelSpeeds {
    pub left_mm_s: f64,
    pub right_mm_s: f64,
}

impl WheelSpeeds {
    /// The body's speed along its heading, mm/s: the wheels' mean.
    pub fn forward_mm_s(self) -> f64 {
        (self.left_mm_s + self.right_mm_s) / 2.0
    }
}

/// Where a proximity sensor sits on the body (x forward, y left) and where it looks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SensorMount {
    pub x_mm: f64,
    pub y_mm: f64,
    pub angle_rad: f64,
}

/// A round differential-drive robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RobotModel {
    pub name: String,
    pub radius_mm: f64,
    pub wheel_base_mm: f64,
    /// Odometry resolution: wheel travel per encoder pulse.
    pub mm_per_pulse: f64,
    /// Largest wheel speed the on-board controller accepts.
    pub max_wheel_speed_mm_s: f64,
    /// Beyond this distance the proximity sensors read only noise.
    pub sensor_range_mm: f64,
    pub sensors: Vec<SensorMount>,
    /// How the wheels follow a commanded speed.
    #[serde(default)]
    pub response: SpeedResponse,
    /// Standard deviation of a wheel's travel error per √mm it travels:
    /// how fast odometry alone grows uncertain (`vl sim odometry`
    /// measures it by UMBmark squares).
    #[serde(default = "default_wheel_slip")]
    pub wheel_slip: f64,
}

/// The Khepera's wheel slip as `vl sim odometry` measured it on the
/// simulated robot over 400 squares (0.0137), rounded up: the simulator's
/// floor is kinder than a bench's, and an estimate that doubts itself a
/// little more only keeps the robot further from walls.
pub const KHEPERA_WHEEL_SLIP: f64 = 0.015;

fn default_wheel_slip() -> f64 {
    KHEPERA_WHEEL_SLIP
}

/// How a wheel's speed follows its command: the on-board controller's
/// first-order response, limited in acceleration, after a dead time. The
/// simulator moves its wheels by it, the Host's safety layer brakes by it,
/// and `vl khepera characterise` measures it on a real robot.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SpeedResponse {
    /// Steady speed over commanded speed.
    pub gain: f64,
    /// Time constant of the first-order response, s.
    pub time_constant_s: f64,
    /// The largest change of speed per second the motors manage, mm/s².
    pub max_accel_mm_s2: f64,
    /// Time from a command to the first change of speed, s.
    pub dead_time_s: f64,
}

/// Within this of its target a wheel has settled on it, mm/s (less than a
/// pulse per 10 ms).
const SETTLED_MM_S: f64 = 1.0;

impl Default for SpeedResponse {
    /// The Khepera's controller: 30 ms, 4 m/s².
    fn default() -> Self {
        SpeedResponse {
            gain: 1.0,
            time_constant_s: 0.03,
            max_accel_mm_s2: 4000.0,
            dead_time_s: 0.0,
        }
    }
}

impl SpeedResponse {
    /// A wheel's speed `dt_s` after it ran at `now` with `command` in force
    /// (the dead time aside).
    pub fn step(&self, now: f64, command: f64, dt_s: f64) -> f64 {
        let want = command * self.gain;
        let change = (want - now) * (1.0 - (-dt_s / self.time_constant_s.max(1e-6)).exp());
        let limit = self.max_accel_mm_s2 * dt_s;
        let next = now + change.clamp(-limit, limit);
        if (want - next).abs() < SETTLED_MM_S {
            want
        } else {
            next
        }
    }

    /// How far a wheel at `speed_mm_s` rolls once commanded to stop, mm.
    pub fn stopping_distance_mm(&self, speed_mm_s: f64) -> f64 {
        let v = speed_mm_s.abs();
        let (a, tau) = (self.max_accel_mm_s2, self.time_constant_s);
        // Rate-limited down to a·τ, then exponential.
        let braking = if v > a * tau {
            (v * v - (a * tau).powi(2)) / (2.0 * a) + a * tau * tau
        } else {
            v * tau
        };
        v * self.dead_time_s + braking
    }

    /// Whether every figure is one a motor can have.
    pub fn check(&self) -> Result<(), RobotModelError> {
        let figures = [
            ("gain", self.gain, false),
            ("time constant", self.time_constant_s, true),
            ("acceleration", self.max_accel_mm_s2, false),
            ("dead time", self.dead_time_s, true),
        ];
        for (what, v, zero_ok) in figures {
            if !(v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0))) {
                return Err(RobotModelError::Response { what, value: v });
            }
        }
        Ok(())
    }
}

/// A robot model that no robot can have, or a file that holds none.
#[derive(Debug, thiserror::Error)]
pub enum RobotModelError {
    #[error("robot model file: {0}")]
    Json(#[source] serde_json::Error),
    #[error("the robot's {what} must be a positive number, not {value}")]
    NotPositive { what: &'static str, value: f64 },
    #[error("a wheel base of {wheel_base_mm} mm does not fit a body of radius {radius_mm} mm")]
    TooWide { wheel_base_mm: f64, radius_mm: f64 },
    #[error("sensor {0} is not at a finite place")]
    SensorNotFinite(usize),
    #[error("the robot's wheel slip must be from 0 to 1 mm per √mm, not {0}")]
    WheelSlip(f64),
    #[error("the speed response's {what} cannot be {value}")]
    Response { what: &'static str, value: f64 },
}

/// Whether wheels `wheel_base_mm` apart fit under a body of `radius_mm`.
fn fits(radius_mm: f64, wheel_base_mm: f64) -> Result<(), RobotModelError> {
    if wheel_base_mm > 2.0 * radius_mm {
        return Err(RobotModelError::TooWide {
            wheel_base_mm,
            radius_mm,
        });
    }
    Ok(())
}

/// The robots `vl` knows by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RobotKind {
    KheperaII,
    KheperaI,
}

impl Named for RobotKind {
    const KIND: &'static str = "robot";
    const ALL: &'static [Self] = &[RobotKind::KheperaII, RobotKind::KheperaI];

    fn id(self) -> &'static str {
        match self {
            RobotKind::KheperaII => "khepera-ii",
            RobotKind::KheperaI => "khepera-i",
        }
    }
}

crate::named_by_id!(RobotKind);

impl RobotKind {
    pub fn model(self) -> RobotModel {
        match self {
            RobotKind::KheperaII => RobotModel::khepera_ii(),
            RobotKind::KheperaI => RobotModel::khepera_i(),
        }
    }
}

/// The Khepera's speed unit is encoder pulses per this period (its on-board
/// speed controller's), s.
pub(crate) const SPEED_PERIOD_S: f64 = 0.01;
/// The firmware's speed limit, pulses per speed period.
pub const MAX_PULSES_PER_PERIOD: i64 = 127;
/// The position controller's largest acceleration (`J`), in its unit:
/// 1/256 pulse per speed period, per speed period.
pub const MAX_PROFILE_ACCEL: i64 = 255;

impl RobotModel {
    /// A wheel speed in the firmware's unit, pulses per 10 ms (rounded).
    pub fn pulses_per_period(&self, mm_s: f64) -> i64 {
        (mm_s * SPEED_PERIOD_S / self.mm_per_pulse).round() as i64
    }

    /// A speed in pulses per 10 ms, in mm/s.
    pub fn speed_mm_s(&self, pulses: i64) -> f64 {
        pulses as f64 * self.mm_per_pulse / SPEED_PERIOD_S
    }

    /// The acceleration position moves are given (`J`), in the firmware's
    /// unit: its largest, or less if the motors manage less.
    pub fn profile_accel(&self) -> i64 {
        let most = (self.response.max_accel_mm_s2 / self.profile_accel_unit()).floor();
        (most.clamp(1.0, MAX_PROFILE_ACCEL as f64)) as i64
    }

    /// The same, mm/s²: how hard a leashed wheel brakes by itself.
    pub fn profile_accel_mm_s2(&self) -> f64 {
        self.profile_accel() as f64 * self.profile_accel_unit()
    }

    /// One unit of the profile's acceleration, mm/s².
    pub fn profile_accel_unit(&self) -> f64 {
        self.mm_per_pulse / 256.0 / (SPEED_PERIOD_S * SPEED_PERIOD_S)
    }

    /// K-Team Khepera II: 70 mm body, 8 IR sensors reaching ≈100 mm.
    pub fn khepera_ii() -> Self {
        Self::khepera("khepera-ii", 35.0, 100.0)
    }

    /// K-Team Khepera I: 55 mm body, IR reaching ≈50 mm.
    pub fn khepera_i() -> Self {
        Self::khepera("khepera-i", 27.5, 50.0)
    }

    /// A robot model from its JSON file (as `vl khepera characterise`
    /// writes), checked to be one that can exist.
    pub fn from_json(text: &str) -> Result<RobotModel, RobotModelError> {
        let model: RobotModel = serde_json::from_str(text).map_err(RobotModelError::Json)?;
        model.check()?;
        Ok(model)
    }

    /// Whether every figure is one a robot can have.
    pub fn check(&self) -> Result<(), RobotModelError> {
        let sizes = [
            ("radius", self.radius_mm),
            ("wheel base", self.wheel_base_mm),
            ("mm per pulse", self.mm_per_pulse),
            ("top wheel speed", self.max_wheel_speed_mm_s),
            ("sensor range", self.sensor_range_mm),
        ];
        for (what, v) in sizes {
            if !(v.is_finite() && v > 0.0) {
                return Err(RobotModelError::NotPositive { what, value: v });
            }
        }
        fits(self.radius_mm, self.wheel_base_mm)?;
        if let Some(i) = self
            .sensors
            .iter()
            .position(|s| !(s.x_mm.is_finite() && s.y_mm.is_finite() && s.angle_rad.is_finite()))
        {
            return Err(RobotModelError::SensorNotFinite(i));
        }
        if !(self.wheel_slip.is_finite() && (0.0..=1.0).contains(&self.wheel_slip)) {
            return Err(RobotModelError::WheelSlip(self.wheel_slip));
        }
        self.response.check()
    }

    /// The same robot built to another size: the body's radius and the
    /// distance between the wheels; the sensors move out with the body.
    pub fn resized(mut self, radius_mm: f64, wheel_base_mm: f64) -> Result<Self, RobotModelError> {
        for (what, v) in [("radius", radius_mm), ("wheel base", wheel_base_mm)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(RobotModelError::NotPositive { what, value: v });
            }
        }
        fits(radius_mm, wheel_base_mm)?;
        let scale = radius_mm / self.radius_mm;
        for mount in &mut self.sensors {
            mount.x_mm *= scale;
            mount.y_mm *= scale;
        }
        self.radius_mm = radius_mm;
        self.wheel_base_mm = wheel_base_mm;
        self.name = format!("{} ({radius_mm} mm)", self.name);
        Ok(self)
    }

    fn khepera(name: &str, radius_mm: f64, sensor_range_mm: f64) -> Self {
        // Sensor placement from K-Team's documentation (x forward, y left).
        let layout = [
            (10.0, 24.0, 90.0),
            (19.0, 17.0, 45.0),
            (25.0, 6.0, 0.0),
            (25.0, -6.0, 0.0),
            (19.0, -17.0, -45.0),
            (10.0, -24.0, -90.0),
            (-24.0, -10.0, 180.0),
            (-24.0, 10.0, 180.0),
        ];
        let mm_per_pulse = 0.08;
        Self {
            name: name.to_owned(),
            radius_mm,
            wheel_base_mm: 53.0,
            mm_per_pulse,
            max_wheel_speed_mm_s: MAX_PULSES_PER_PERIOD as f64 * mm_per_pulse / SPEED_PERIOD_S,
            sensor_range_mm,
            response: SpeedResponse::default(),
            wheel_slip: KHEPERA_WHEEL_SLIP,
            sensors: layout
                .iter()
                .map(|&(x_mm, y_mm, deg)| SensorMount {
                    x_mm,
                    y_mm,
                    angle_rad: f64::to_radians(deg),
                })
                .collect(),
        }
    }

    /// Scales `wheels` down (keeping their ratio, so the path's curvature)
    /// until both are within the speed limit; speeds that are not finite
    /// numbers stop the robot.
    pub fn clamp(&self, wheels: WheelSpeeds) -> WheelSpeeds {
        if !(wheels.left_mm_s.is_finite() && wheels.right_mm_s.is_finite()) {
            return WheelSpeeds::default();
        }
        let peak = wheels.left_mm_s.abs().max(wheels.right_mm_s.abs());
        if peak <= self.max_wheel_speed_mm_s || peak == 0.0 {
            return wheels;
        }
        let k = self.max_wheel_speed_mm_s / peak;
        WheelSpeeds {
            left_mm_s: wheels.left_mm_s * k,
            right_mm_s: wheels.right_mm_s * k,
        }
    }

    /// Where the robot at `pose` with its wheels at `wheels` is `dt_s`
    /// later with `asked` in force, and its wheels then: each wheel through
    /// the speed response, the pose along the step's mean speeds. The one
    /// way the safety layer's braking check and the Guest's prediction
    /// carry the robot forward.
    pub fn respond(
        &self,
        pose: Pose,
        wheels: WheelSpeeds,
        asked: WheelSpeeds,
        dt_s: f64,
    ) -> (Pose, WheelSpeeds) {
        let response = &self.response;
        let next = WheelSpeeds {
            left_mm_s: response.step(wheels.left_mm_s, asked.left_mm_s, dt_s),
            right_mm_s: response.step(wheels.right_mm_s, asked.right_mm_s, dt_s),
        };
        let mean = WheelSpeeds {
            left_mm_s: (wheels.left_mm_s + next.left_mm_s) / 2.0,
            right_mm_s: (wheels.right_mm_s + next.right_mm_s) / 2.0,
        };
        (pose.advance(mean, self.wheel_base_mm, dt_s), next)
    }

    /// Wheel speeds for a linear speed `v` (mm/s) and turn rate `w` (rad/s).
    /// Each is first saturated to what the wheels can do (a turn rate no
    /// faster than both wheels at full speed in opposite directions), so
    /// that a huge number means "as fast as possible", not infinity.
    pub fn wheels_for(&self, v_mm_s: f64, w_rad_s: f64) -> WheelSpeeds {
        let top = self.max_wheel_speed_mm_s;
        let v_mm_s = v_mm_s.clamp(-top, top);
        let w_rad_s = w_rad_s.clamp(
            -2.0 * top / self.wheel_base_mm,
            2.0 * top / self.wheel_base_mm,
        );
        let half = w_rad_s * self.wheel_base_mm / 2.0;
        self.clamp(WheelSpeeds {
            left_mm_s: v_mm_s - half,
            right_mm_s: v_mm_s + half,
        })
    }
}

impl Pose {
    /// Differential-drive forward kinematics: the pose after driving the
    /// wheels at constant `wheels` for `dt_s`, integrated exactly along the arc.
    pub fn advance(&self, wheels: WheelSpeeds, wheel_base_mm: f64, dt_s: f64) -> Pose {
        let v = (wheels.left_mm_s + wheels.right_mm_s) / 2.0;
        let w = (wheels.right_mm_s - wheels.left_mm_s) / wheel_base_mm;
        let dtheta = w * dt_s;
        let (dx, dy) = if dtheta.abs() < 1e-9 {
            let d = v * dt_s;
            (d * self.theta_rad.cos(), d * self.theta_rad.sin())
        } else {
            let r = v / w;
            (
                r * ((self.theta_rad + dtheta).sin() - self.theta_rad.sin()),
                -r * ((self.theta_rad + dtheta).cos() - self.theta_rad.cos()),
            )
        };
        Pose {
            x_mm: self.x_mm + dx,
            y_mm: self.y_mm + dy,
            theta_rad: wrap_angle(self.theta_rad + dtheta),
        }
    }

    /// The pose's position.
    pub fn point(&self) -> Point {
        Point {
            x_mm: self.x_mm,
            y_mm: self.y_mm,
        }
    }

    /// A point given in the robot's body frame (x forward, y left), in the arena frame.
    pub fn to_world(&self, x_mm: f64, y_mm: f64) -> Point {
        let (s, c) = self.theta_rad.sin_cos();
        Point {
            x_mm: self.x_mm + c * x_mm - s * y_mm,
            y_mm: self.y_mm + s * x_mm + c * y_mm,
        }
    }
}

impl Point {
    /// Euclidean distance to `other`.
    pub fn distance(&self, other: Point) -> f64 {
        (self.x_mm - other.x_mm).hypot(self.y_mm - other.y_mm)
    }

    /// Distance to the segment from `a` to `b`.
    pub fn distance_to_segment(&self, a: Point, b: Point) -> f64 {
        let (dx, dy) = (b.x_mm - a.x_mm, b.y_mm - a.y_mm);
        let len2 = dx * dx + dy * dy;
        let t = if len2 == 0.0 {
            0.0
        } else {
            (((self.x_mm - a.x_mm) * dx + (self.y_mm - a.y_mm) * dy) / len2).clamp(0.0, 1.0)
        };
        (self.x_mm - (a.x_mm + t * dx)).hypot(self.y_mm - (a.y_mm + t * dy))
    }
}

/// Points `x,y;x,y;…`, mm.
pub(crate) fn parse_points(text: &str) -> Result<Vec<Point>, SyntaxError> {
    text.split(';').map(|pair| pair.parse()).collect()
}

/// `x,y` in mm.
impl FromStr for Point {
    type Err = SyntaxError;

    fn from_str(text: &str) -> Result<Point, SyntaxError> {
        match *parse_numbers(text)?.as_slice() {
            [x_mm, y_mm] => Ok(Point { x_mm, y_mm }),
            _ => Err(SyntaxError::Form {
                expected: "expected a point x,y in mm",
                got: text.to_owned(),
            }),
        }
    }
}

/// `x,y` or `x,y,θ`: mm, and radians counter-clockwise from +x.
impl FromStr for Pose {
    type Err = SyntaxError;

    fn from_str(text: &str) -> Result<Pose, SyntaxError> {
        match *parse_numbers(text)?.as_slice() {
            [x_mm, y_mm] => Ok(Pose {
                x_mm,
                y_mm,
                theta_rad: 0.0,
            }),
            [x_mm, y_mm, theta_rad] => Ok(Pose {
                x_mm,
                y_mm,
                theta_rad,
            }),
            _ => Err(SyntaxError::Form {
                expected: "expected x,y or x,y,θ",
                got: text.to_owned(),
            }),
        }
    }
}

/// `a` folded into (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let t = a.rem_euclid(std::f64::consts::TAU);
    if t > std::f64::consts::PI {
        t - std::f64::consts::TAU
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    #[test]
    fn spinning_in_place_keeps_position() {
        let m = RobotModel::khepera_ii();
        let p = Pose::default().advance(m.wheels_for(0.0, PI / 2.0), m.wheel_base_mm, 1.0);
        assert!(p.x_mm.abs() < 1e-9 && p.y_mm.abs() < 1e-9);
        assert!((p.theta_rad - PI / 2.0).abs() < 1e-9);
    }

    #[test]
    fn half_circle_ends_two_radii_away() {
        // v = 100 mm/s, w = π rad/s for 1 s: half a circle of radius 100/π.
        let m = RobotModel::khepera_ii();
        let p = Pose::default().advance(m.wheels_for(100.0, PI), m.wheel_base_mm, 1.0);
        assert!(p.x_mm.abs() < 1e-9);
        assert!((p.y_mm - 200.0 / PI).abs() < 1e-9);
    }

    #[test]
    fn a_resized_robot_keeps_its_sensors_on_its_body() {
        let big = RobotModel::khepera_ii().resized(70.0, 100.0).unwrap();
        assert_eq!((big.radius_mm, big.wheel_base_mm), (70.0, 100.0));
        for (m, k) in big.sensors.iter().zip(&RobotModel::khepera_ii().sensors) {
            assert_eq!(
                (m.x_mm, m.y_mm, m.angle_rad),
                (2.0 * k.x_mm, 2.0 * k.y_mm, k.angle_rad)
            );
        }
        let e = RobotModel::khepera_ii().resized(-1.0, 53.0).unwrap_err();
        assert!(e.to_string().contains("radius must be a positive"), "{e}");
        let e = RobotModel::khepera_ii().resized(20.0, 53.0).unwrap_err();
        assert!(e.to_string().contains("does not fit"), "{e}");
        assert_eq!(
            "khepera-i".parse::<RobotKind>().map(RobotKind::model),
            Ok(RobotModel::khepera_i())
        );
        let e = "roomba".parse::<RobotKind>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown robot 'roomba' (known: khepera-ii, khepera-i)"
        );
    }

    #[test]
    fn poses_and_points_are_written_as_numbers() {
        assert_eq!(
            "1,2".parse(),
            Ok(Pose {
                x_mm: 1.0,
                y_mm: 2.0,
                theta_rad: 0.0
            })
        );
        assert_eq!("1, 2, 0.5".parse::<Pose>().map(|p| p.theta_rad), Ok(0.5));
        assert!(
            "1".parse::<Pose>()
                .unwrap_err()
                .to_string()
                .contains("x,y or x,y,θ")
        );
        assert!(
            "1,inf"
                .parse::<Pose>()
                .unwrap_err()
                .to_string()
                .contains("not a finite")
        );
        assert!("1,2,3".parse::<Point>().is_err());
        let p = Point {
            x_mm: 5.0,
            y_mm: 5.0,
        };
        let (a, b) = (
            Point::default(),
            Point {
                x_mm: 10.0,
                y_mm: 0.0,
            },
        );
        assert_eq!(p.distance_to_segment(a, b), 5.0);
        assert_eq!(p.distance_to_segment(a, a), p.distance(a));
    }

    proptest! {
        /// Integrating in many small steps gives the same pose as one exact step.
        #[test]
        fn advance_composes(l in -500.0f64..500.0, r in -500.0f64..500.0, theta in -PI..PI) {
            let wheels = WheelSpeeds { left_mm_s: l, right_mm_s: r };
            let start = Pose { x_mm: 10.0, y_mm: -5.0, theta_rad: theta };
            let once = start.advance(wheels, 53.0, 0.5);
            let mut stepped = start;
            for _ in 0..50 { stepped = stepped.advance(wheels, 53.0, 0.01); }
            prop_assert!((once.x_mm - stepped.x_mm).abs() < 1e-6);
            prop_assert!((once.y_mm - stepped.y_mm).abs() < 1e-6);
            prop_assert!(wrap_angle(once.theta_rad - stepped.theta_rad).abs() < 1e-9);
        }

        /// Braking by the response law, stepped finely, rolls as far as
        /// the closed form says.
        #[test]
        fn stopping_distance_is_what_braking_rolls(v in 0.0f64..2000.0, tau in 0.005f64..0.2, a in 500.0f64..20000.0) {
            let r = SpeedResponse { gain: 1.0, time_constant_s: tau, max_accel_mm_s2: a, dead_time_s: 0.0 };
            let (mut speed, mut rolled, dt) = (v, 0.0, 1e-5);
            while speed > 0.0 {
                let next = r.step(speed, 0.0, dt);
                rolled += (speed + next) / 2.0 * dt;
                speed = next;
            }
            let want = r.stopping_distance_mm(v);
            prop_assert!((rolled - want).abs() <= 0.01 * want + SETTLED_MM_S * tau + 1e-6, "{} vs {}", rolled, want);
        }

        #[test]
        fn clamp_keeps_ratio_and_limit(l in -5000.0f64..5000.0, r in -5000.0f64..5000.0) {
            let m = RobotModel::khepera_ii();
            let c = m.clamp(WheelSpeeds { left_mm_s: l, right_mm_s: r });
            prop_assert!(c.left_mm_s.abs() <= m.max_wheel_speed_mm_s + 1e-9);
            prop_assert!(c.right_mm_s.abs() <= m.max_wheel_speed_mm_s + 1e-9);
            prop_assert!((c.left_mm_s * r - c.right_mm_s * l).abs() < 1e-6 * (1.0 + l.abs() * r.abs()));
        }

        /// Whatever numbers arrive, the wheels get finite speeds within the limit.
        #[test]
        fn any_numbers_become_finite_limited_speeds(v in prop::num::f64::ANY, w in prop::num::f64::ANY) {
            let m = RobotModel::khepera_ii();
            let c = m.wheels_for(v, w);
            prop_assert!(c.left_mm_s.is_finite() && c.right_mm_s.is_finite());
            prop_assert!(c.left_mm_s.abs() <= m.max_wheel_speed_mm_s + 1e-9);
            prop_assert!(c.right_mm_s.abs() <= m.max_wheel_speed_mm_s + 1e-9);
        }
    }
}
