//! Teleoperation with force feedback: the joystick sets a desired velocity,
//! obstacles push back through potential fields (one from the proximity
//! sensors, one over the known map), the robot gets the sum within its
//! limits, and the joystick renders the push as a force, so the operator
//! feels an obstacle before the robot touches it. Forward kinematics
//! predicts where the robot is while feedback is still on its way.
//!
//! Velocities here are vectors in the robot's frame (x forward, y left,
//! mm/s); a differential drive turns the sideways part into a turn.

use crate::Grid;
use crate::{Point, Pose, RobotModel, WheelSpeeds};

/// A planar vector, mm/s unless said otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vector {
    pub x: f64,
    pub y: f64,
}

impl Vector {
    fn add(self, o: Vector) -> Vector {
        Vector {
            x: self.x + o.x,
            y: self.y + o.y,
        }
    }

    fn scale(self, k: f64) -> Vector {
        Vector {
            x: self.x * k,
            y: self.y * k,
        }
    }

    /// The same vector seen from a frame turned by `theta` (world → robot
    /// for the robot's heading).
    pub fn rotated(self, theta: f64) -> Vector {
        let (s, c) = theta.sin_cos();
        Vector {
            x: c * self.x + s * self.y,
            y: -s * self.x + c * self.y,
        }
    }
}

/// The joystick's deflection: x to the right, y forward, each −1 to 1.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Joystick {
    pub x: f64,
    pub y: f64,
}

/// Gains of the teleoperation laws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Teleop {
    /// Speed at full deflection, mm/s.
    pub max_speed_mm_s: f64,
    /// Push at a full proximity reading, mm/s.
    pub sensor_gain: f64,
    /// Readings at or below this are the sensors' noise floor: no push.
    pub sensor_floor: u16,
    /// rad/s of turn per mm/s of sideways velocity, per mm of wheel base.
    pub turn_per_sideways: f64,
    /// How much of the fields' sideways push turns the robot (0–1): a
    /// differential drive cannot slide, and turning by the whole push
    /// steers it away from where the stick points.
    pub turn_guidance: f64,
}

impl Default for Teleop {
    fn default() -> Self {
        Teleop {
            max_speed_mm_s: 200.0,
            sensor_gain: 300.0,
            sensor_floor: 100,
            turn_per_sideways: 1.0,
            turn_guidance: 0.3,
        }
    }
}

/// What the laws give for one period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assisted {
    pub wheels: WheelSpeeds,
    /// The force to render, in joystick axes (x right, y forward), −1 to 1.
    pub force: [f64; 2],
}

impl Teleop {
    /// The velocity the operator asks for.
    pub fn desired(&self, joystick: Joystick) -> Vector {
        let clamp = |v: f64| {
            if v.is_finite() {
                v.clamp(-1.0, 1.0)
            } else {
                0.0
            }
        };
        Vector {
            x: clamp(joystick.y) * self.max_speed_mm_s,
            y: -clamp(joystick.x) * self.max_speed_mm_s,
        }
    }

    /// The sensors' potential-field velocity: each sensor pushes opposite
    /// to the way it looks, rising with the square of its reading above
    /// the noise floor.
    pub fn sensor_field(&self, robot: &RobotModel, proximity: &[u16]) -> Vector {
        let span = f64::from(1023u16.saturating_sub(self.sensor_floor).max(1));
        robot
            .sensors
            .iter()
            .zip(proximity)
            .fold(Vector::default(), |sum, (mount, &reading)| {
                let r = (f64::from(reading.saturating_sub(self.sensor_floor)) / span).min(1.0);
                let (s, c) = mount.angle_rad.sin_cos();
                sum.add(Vector { x: -c, y: -s }.scale(self.sensor_gain * r * r))
            })
    }

    /// Wheel speeds for a velocity vector in the robot's frame: the forward
    /// part drives, the sideways part turns toward its side.
    pub fn wheels(&self, robot: &RobotModel, velocity: Vector) -> WheelSpeeds {
        let w = self.turn_per_sideways * velocity.y / robot.wheel_base_mm;
        robot.wheels_for(velocity.x, w)
    }

    /// Desired plus field, within the robot's limits; the field, scaled to
    /// the joystick, is the force fed back. The field acts only while the
    /// stick asks for motion (at rest the robot stops), may slow the robot
    /// down to a stop but never drives it against the stick or faster than
    /// asked, and deflects it by a share of its sideways push — in
    /// proportion to the forward speed it leaves: a robot the field holds
    /// still against a wall is not turned in place by the sideways part of
    /// the push (which grows as it turns), since nobody asked for a turn.
    pub fn assist(&self, robot: &RobotModel, desired: Vector, field: Vector) -> Assisted {
        let finite = |v: Vector| {
            if v.x.is_finite() && v.y.is_finite() {
                v
            } else {
                Vector::default()
            }
        };
        let (desired, field) = (finite(desired), finite(field));
        let to_stick = |v: f64| (v / self.max_speed_mm_s).clamp(-1.0, 1.0);
        let force = [to_stick(-field.y), to_stick(field.x)];
        if desired == Vector::default() {
            return Assisted {
                wheels: WheelSpeeds::default(),
                force,
            };
        }
        let forward = (desired.x + field.x).clamp(desired.x.min(0.0), desired.x.max(0.0));
        let moving = if desired.x == 0.0 {
            0.0
        } else {
            forward / desired.x
        };
        let sideways = desired.y + self.turn_guidance * field.y * moving;
        Assisted {
            wheels: self.wheels(
                robot,
                Vector {
                    x: forward,
                    y: sideways,
                },
            ),
            force,
        }
    }

    /// The velocity vector that [`Teleop::wheels`] turns into linear speed
    /// `v_mm_s` and turn rate `w_rad_s`: what a Guest sending velocities
    /// rather than stick positions desires.
    pub fn velocity_for(&self, robot: &RobotModel, v_mm_s: f64, w_rad_s: f64) -> Vector {
        Vector {
            x: v_mm_s,
            y: w_rad_s * robot.wheel_base_mm / self.turn_per_sideways,
        }
    }
}

/// A numeric potential field over a known map: zero beyond an influence
/// distance from obstacles, rising as ½·η·(1/d − 1/d₀)² nearer; its negative
/// gradient is a velocity away from them.
#[derive(Debug, Clone)]
pub struct MapField {
    grid: Grid,
    potential: Vec<f64>,
}

impl MapField {
    /// The field of `grid`'s blocked cells and edges, felt within
    /// `influence_mm`, with strength `eta` (mm³/s: the push at distance d is
    /// about η/d² close in).
    pub fn new(grid: &Grid, influence_mm: f64, eta: f64) -> MapField {
        let d2 = grid.distance_transform();
        let s = grid.cell_mm;
        let mut potential = vec![0.0; d2.len()];
        for r in 0..grid.height {
            for c in 0..grid.width {
                let i = grid.index(c, r);
                let d =
                    (f64::from(d2[i]).sqrt().min(grid.border_cells(c, r) - 0.5) * s).max(s * 0.5);
                if d < influence_mm {
                    let k = 1.0 / d - 1.0 / influence_mm;
                    potential[i] = 0.5 * eta * k * k;
                }
            }
        }
        MapField {
            grid: grid.clone(),
            potential,
        }
    }

    /// The potential at `p` (its cell's; infinite off the map).
    pub fn potential(&self, p: Point) -> f64 {
        self.grid.cell_of(p).map_or(f64::INFINITY, |(c, r)| {
            self.potential[self.grid.index(c, r)]
        })
    }

    /// −∇U at `p` in the world frame, by central differences over cells.
    pub fn guidance(&self, p: Point) -> Vector {
        let Some((c, r)) = self.grid.cell_of(p) else {
            return Vector::default();
        };
        let at = |dc: i64, dr: i64| {
            let (cc, rr) = (i64::from(c) + dc, i64::from(r) + dr);
            if cc < 0
                || rr < 0
                || cc >= i64::from(self.grid.width)
                || rr >= i64::from(self.grid.height)
            {
                self.potential[self.grid.index(c, r)]
            } else {
                self.potential[self.grid.index(cc as u32, rr as u32)]
            }
        };
        let span = 2.0 * self.grid.cell_mm;
        // Rows run down, y up: the row above has the larger y.
        Vector {
            x: -(at(1, 0) - at(-1, 0)) / span,
            y: -(at(0, -1) - at(0, 1)) / span,
        }
    }
}

/// Where the robot will be after the wheel commands `history` (speeds and
/// how long each holds), starting from `pose`: the Guest's prediction of
/// the present while the feedback describing it is still in flight.
pub fn predict(robot: &RobotModel, pose: Pose, history: &[(WheelSpeeds, f64)]) -> Pose {
    history.iter().fold(pose, |p, &(wheels, dt_s)| {
        p.advance(robot.clamp(wheels), robot.wheel_base_mm, dt_s)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn with_nothing_near_the_robot_does_what_the_stick_says() {
        let robot = RobotModel::khepera_ii();
        let t = Teleop::default();
        let stick = |x, y| t.desired(Joystick { x, y });
        let forward = t.assist(&robot, stick(0.0, 0.5), t.sensor_field(&robot, &[0; 8]));
        assert_eq!(forward.force, [0.0, 0.0]);
        assert!((forward.wheels.left_mm_s - 100.0).abs() < 1e-9);
        assert_eq!(forward.wheels.left_mm_s, forward.wheels.right_mm_s);
        let left = t.assist(&robot, stick(-1.0, 0.0), Vector::default());
        let asked = t.velocity_for(&robot, 80.0, 0.5);
        let w = t.wheels(&robot, asked);
        assert_eq!(w, robot.wheels_for(80.0, 0.5));
        assert!(left.wheels.right_mm_s > left.wheels.left_mm_s, "{left:?}");
    }

    #[test]
    fn an_obstacle_ahead_pushes_back_and_is_felt() {
        let robot = RobotModel::khepera_ii();
        let t = Teleop::default();
        // The two front sensors read high.
        let field = t.sensor_field(&robot, &[0, 0, 900, 900, 0, 0, 0, 0]);
        assert!(field.x < -100.0 && field.y.abs() < 1e-6, "{field:?}");
        let full = t.desired(Joystick { x: 0.0, y: 1.0 });
        let a = t.assist(&robot, full, field);
        assert!(
            a.wheels.left_mm_s <= (200.0 + field.x).max(0.0) + 1e-6,
            "{a:?}"
        );
        assert!(a.force[1] < -0.5, "pushed back toward the operator: {a:?}");
        // Full deflection into a wall at full reading: the robot is held.
        let wall = t.sensor_field(&robot, &[0, 0, 1023, 1023, 0, 0, 0, 0]);
        let held = t.assist(&robot, full, wall);
        assert!(held.wheels.left_mm_s <= 1e-6, "{held:?}");
    }

    #[test]
    fn the_map_field_points_away_from_obstacles_and_vanishes_far_off() {
        let mut grid = Grid::free(60, 20, 5.0).unwrap();
        for r in 0..20 {
            let i = grid.index(30, r);
            grid.blocked[i] = true;
        }
        let field = MapField::new(&grid, 40.0, 1e5);
        let left_of_wall = field.guidance(Point {
            x_mm: 140.0,
            y_mm: 50.0,
        });
        assert!(
            left_of_wall.x < 0.0 && left_of_wall.y.abs() < 1e-9,
            "{left_of_wall:?}"
        );
        let right_of_wall = field.guidance(Point {
            x_mm: 168.0,
            y_mm: 50.0,
        });
        assert!(right_of_wall.x > 0.0);
        let far = field.guidance(Point {
            x_mm: 60.0,
            y_mm: 50.0,
        });
        assert_eq!(far, Vector::default());
    }

    fn vector() -> impl Strategy<Value = Vector> {
        (-2000.0f64..2000.0, -2000.0f64..2000.0).prop_map(|(x, y)| Vector { x, y })
    }

    proptest! {
        /// The stick at rest stops the robot whatever the fields say, and
        /// the force felt is the field, within the stick's range.
        #[test]
        fn at_rest_the_robot_stops_and_the_field_is_felt(field in vector()) {
            let t = Teleop::default();
            let robot = RobotModel::khepera_ii();
            let a = t.assist(&robot, Vector::default(), field);
            prop_assert_eq!(a.wheels, WheelSpeeds::default());
            prop_assert!(a.force.iter().all(|f| (-1.0..=1.0).contains(f)));
            let expect = (field.x / t.max_speed_mm_s).clamp(-1.0, 1.0);
            prop_assert!((a.force[1] - expect).abs() < 1e-12);
        }

        /// The fields may slow the robot, never push it faster than asked
        /// or against the stick.
        #[test]
        fn the_fields_never_drive_against_the_stick(stick_x in -1.0f64..1.0, stick_y in -1.0f64..1.0, field in vector()) {
            let t = Teleop::default();
            let robot = RobotModel::khepera_ii();
            let desired = t.desired(Joystick { x: stick_x, y: stick_y });
            prop_assume!(desired != Vector::default());
            let a = t.assist(&robot, desired, field);
            let forward = (a.wheels.left_mm_s + a.wheels.right_mm_s) / 2.0;
            prop_assert!(forward * desired.x >= -1e-9, "{:?} for {:?}", a, desired);
            prop_assert!(forward.abs() <= desired.x.abs() + 1e-9);
        }

        /// Pushed straight on, the fields never turn a robot they have
        /// stopped, whatever their sideways part.
        #[test]
        fn a_robot_held_still_is_not_turned(stick_x in -1.0f64..1.0, field in vector()) {
            let t = Teleop::default();
            let robot = RobotModel::khepera_ii();
            let desired = t.desired(Joystick { x: 0.0, y: stick_x });
            prop_assume!(desired.x != 0.0);
            let held = Vector { x: -desired.x - desired.x.signum() * field.x.abs(), y: field.y };
            let a = t.assist(&robot, desired, held);
            prop_assert_eq!(a.wheels, WheelSpeeds::default(), "{:?}", held);
        }

        /// Each reading sensor pushes away from where it looks.
        #[test]
        fn the_sensor_field_pushes_away_from_what_is_seen(readings in proptest::collection::vec(0u16..=1023, 8)) {
            let t = Teleop::default();
            let robot = RobotModel::khepera_ii();
            let field = t.sensor_field(&robot, &readings);
            let mut toward = 0.0;
            for (mount, &r) in robot.sensors.iter().zip(&readings) {
                if r > t.sensor_floor {
                    toward += field.x * mount.angle_rad.cos() + field.y * mount.angle_rad.sin();
                }
            }
            prop_assert!(field.x.is_finite() && field.y.is_finite());
            if readings.iter().all(|&r| r <= t.sensor_floor) {
                prop_assert_eq!(field, Vector::default());
            } else if readings.iter().filter(|&&r| r > t.sensor_floor).count() == 1 {
                prop_assert!(toward < 0.0, "{:?}", field);
            }
        }
    }

    #[test]
    fn prediction_integrates_the_commands_in_flight() {
        let robot = RobotModel::khepera_ii();
        let straight = WheelSpeeds {
            left_mm_s: 100.0,
            right_mm_s: 100.0,
        };
        let p = predict(
            &robot,
            Pose::default(),
            &[(straight, 0.5), (straight, 0.25)],
        );
        assert!((p.x_mm - 75.0).abs() < 1e-9 && p.y_mm.abs() < 1e-9);
        let spin = WheelSpeeds {
            left_mm_s: -50.0,
            right_mm_s: 50.0,
        };
        let turned = predict(&robot, Pose::default(), &[(spin, 1.0)]);
        assert!((turned.theta_rad - 100.0 / robot.wheel_base_mm).abs() < 1e-9);
    }
}
