//! The simulated robot in its arena, stepped on a virtual clock.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use thiserror::Error;
use vl_core::{
    Arena, Leash, Material, Obstacle, Pose, PositionControl, RobotModel, WheelMove, WheelSpeeds,
    mapped_reading,
};

use crate::noise::gaussian;
use crate::scene::{SceneEvent, Scheduled};

/// The simulator's step: the Khepera's speed-control period.
pub const STEP_S: f64 = 0.01;
/// Commands held back by the dead time, at most.
const MAX_PENDING: usize = 256;
/// Readings past the sensor's range are this noise floor, at most.
const NOISE_FLOOR: f64 = 10.0;
/// Relative noise on an in-range reading.
const READING_NOISE: f64 = 0.03;
/// Standard deviation of each wheel's slip: the fraction of its turning
/// that does not move the body, drawn afresh each step. Encoders count the
/// turning, so odometry drifts from the truth as on the real robot.
const SLIP_SD: f64 = 0.01;

#[derive(Debug, Error, PartialEq)]
pub enum SimError {
    #[error(
        "the robot's start ({x_mm:.0}, {y_mm:.0}) mm overlaps a wall or obstacle of arena '{arena}'"
    )]
    StartBlocked { arena: String, x_mm: f64, y_mm: f64 },
    #[error("arena '{0}' has a non-positive or non-finite size")]
    BadArena(String),
}

/// What the wheels' controllers are told: a speed (`D`), or a move to a
/// target that ends by itself (`C`, and a leash).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Motion {
    Speed(WheelSpeeds),
    Move([WheelMove; 2]),
}

/// The controller that has the wheels: the speed controller, or the
/// position controllers with their moves.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Controller {
    Speed(WheelSpeeds),
    Position([WheelMove; 2], [PositionControl; 2]),
}

/// The robot, its arena and the virtual clock.
#[derive(Debug, Clone)]
pub struct World {
    arena: Arena,
    robot: RobotModel,
    pose: Pose,
    wheels: WheelSpeeds,
    /// Which controller has the wheels, and what it was told.
    controller: Controller,
    /// Commands still within the controller's dead time: when each takes
    /// effect, in order.
    pending: std::collections::VecDeque<(f64, Motion)>,
    steps: u64,
    contact: bool,
    collisions: u64,
    odometer_mm: f64,
    /// Distance each wheel's surface has turned through, mm (left, right);
    /// it keeps turning when the body is stopped against a wall (slip).
    wheel_travel_mm: [f64; 2],
    rng: Pcg64Mcg,
    /// What people will do, latest first.
    scene: Vec<Scheduled>,
    /// A hand covers the robot from the camera until this time, s.
    covered_until_s: f64,
}

impl World {
    /// The robot at the arena's start pose, at rest.
    pub fn new(arena: Arena, robot: RobotModel, seed: u64) -> Result<Self, SimError> {
        let sized = |v: f64| v.is_finite() && v > 0.0;
        if !(sized(arena.width_mm) && sized(arena.height_mm)) {
            return Err(SimError::BadArena(arena.name));
        }
        let start = arena.start;
        if !arena.is_free(start.point(), robot.radius_mm) {
            return Err(SimError::StartBlocked {
                arena: arena.name,
                x_mm: start.x_mm,
                y_mm: start.y_mm,
            });
        }
        Ok(World {
            arena,
            robot,
            pose: start,
            wheels: WheelSpeeds::default(),
            controller: Controller::Speed(WheelSpeeds::default()),
            pending: std::collections::VecDeque::new(),
            steps: 0,
            contact: false,
            collisions: 0,
            odometer_mm: 0.0,
            wheel_travel_mm: [0.0; 2],
            rng: Pcg64Mcg::seed_from_u64(seed),
            scene: Vec::new(),
            covered_until_s: 0.0,
        })
    }

    pub fn arena(&self) -> &Arena {
        &self.arena
    }

    pub fn robot(&self) -> &RobotModel {
        &self.robot
    }

    /// True pose of the robot.
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// Wheel speeds the robot actually has now.
    pub fn wheels(&self) -> WheelSpeeds {
        self.wheels
    }

    /// Virtual time since the start, s.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * STEP_S
    }

    /// Whether the robot is pressing against something.
    pub fn contact(&self) -> bool {
        self.contact
    }

    /// How many times the robot has run into something.
    pub fn collisions(&self) -> u64 {
        self.collisions
    }

    /// Distance the robot's centre has travelled, mm.
    pub fn odometer_mm(&self) -> f64 {
        self.odometer_mm
    }

    /// How far each wheel has turned, mm (left, right): what its encoder counts.
    pub fn wheel_travel_mm(&self) -> [f64; 2] {
        self.wheel_travel_mm
    }

    /// Asks the speed controller for `target` (clamped to the robot's limits).
    /// It takes over after the response's dead time.
    pub fn set_wheels(&mut self, target: WheelSpeeds) {
        let target = self.robot.clamp(target);
        self.tell(Motion::Speed(target));
    }

    /// Asks the position controllers for `moves`, the wheels' travel
    /// measured as [`World::wheel_travel_mm`] does: each wheel goes to its
    /// target and stops there by itself.
    pub fn move_wheels(&mut self, moves: [WheelMove; 2]) {
        let top = self.robot.max_wheel_speed_mm_s;
        let moves = moves.map(|m| WheelMove {
            top_mm_s: if m.top_mm_s.is_finite() {
                m.top_mm_s.abs().min(top)
            } else {
                0.0
            },
            target_mm: if m.target_mm.is_finite() {
                m.target_mm
            } else {
                0.0
            },
            accel_mm_s2: if m.accel_mm_s2.is_finite() {
                m.accel_mm_s2.max(0.0)
            } else {
                0.0
            },
        });
        self.tell(Motion::Move(moves));
    }

    /// Drives by `leash`, its reach counted from the wheels' travel
    /// `from_mm` (when the robot was read); a stop is the speed controller's.
    pub fn drive(&mut self, leash: &Leash, from_mm: [f64; 2]) {
        if leash.is_stop() {
            self.set_wheels(WheelSpeeds::default());
        } else {
            let moves = leash.moves(&self.robot, from_mm);
            self.move_wheels(moves);
        }
    }

    /// The position controllers' targets, while they have the wheels.
    pub fn targets_mm(&self) -> Option<[f64; 2]> {
        match self.controller {
            Controller::Position(moves, _) => Some(moves.map(|m| m.target_mm)),
            Controller::Speed(_) => None,
        }
    }

    fn tell(&mut self, drive: Motion) {
        let dead = self.robot.response.dead_time_s;
        if dead <= 0.0 {
            self.take(drive);
        } else {
            // Commands come a control period apart at most; a flood only
            // ever needs the latest within the dead time.
            if self.pending.len() >= MAX_PENDING {
                self.pending.pop_front();
            }
            self.pending.push_back((self.time_s() + dead, drive));
        }
    }

    /// The controllers take `drive` on: position controllers taking over
    /// from the speed controller start where the wheels are, as fast.
    fn take(&mut self, drive: Motion) {
        self.controller = match (drive, self.controller) {
            (Motion::Speed(target), _) => Controller::Speed(target),
            (Motion::Move(moves), Controller::Position(_, controls)) => {
                Controller::Position(moves, controls)
            }
            (Motion::Move(moves), Controller::Speed(_)) => {
                let w = [self.wheels.left_mm_s, self.wheels.right_mm_s];
                let travel = self.wheel_travel_mm;
                let controls = [0, 1].map(|i| PositionControl::taking_over(travel[i], w[i]));
                Controller::Position(moves, controls)
            }
        };
    }

    /// Has `event` happen when the clock reaches its time.
    pub fn schedule(&mut self, event: Scheduled) {
        self.scene.push(event);
        self.scene.sort_by(|a, b| b.at_s.total_cmp(&a.at_s));
    }

    /// Whether a hand hides the robot from the camera now.
    pub fn robot_covered(&self) -> bool {
        self.time_s() < self.covered_until_s
    }

    /// Advances the clock by one step.
    pub fn step(&mut self) {
        while self.scene.last().is_some_and(|e| e.at_s <= self.time_s()) {
            let Some(Scheduled { at_s, event }) = self.scene.pop() else {
                break;
            };
            match event {
                SceneEvent::Place(shape) => self.arena.obstacles.push(Obstacle {
                    shape,
                    material: Material::default(),
                }),
                SceneEvent::Cover(seconds) => self.covered_until_s = at_s + seconds,
            }
        }
        while let Some(&(due, drive)) = self.pending.front() {
            if due > self.time_s() + 1e-9 {
                break;
            }
            self.take(drive);
            self.pending.pop_front();
        }
        let response = self.robot.response;
        let target = match &mut self.controller {
            Controller::Speed(target) => *target,
            Controller::Position(moves, controls) => {
                let travel = self.wheel_travel_mm;
                let asked: [f64; 2] =
                    [0, 1].map(|i| controls[i].step(&moves[i], travel[i], &response, STEP_S));
                self.robot.clamp(WheelSpeeds {
                    left_mm_s: asked[0],
                    right_mm_s: asked[1],
                })
            }
        };
        let respond = |now: f64, want: f64| response.step(now, want, STEP_S);
        self.wheels = WheelSpeeds {
            left_mm_s: respond(self.wheels.left_mm_s, target.left_mm_s),
            right_mm_s: respond(self.wheels.right_mm_s, target.right_mm_s),
        };
        self.wheel_travel_mm[0] += self.wheels.left_mm_s * STEP_S;
        self.wheel_travel_mm[1] += self.wheels.right_mm_s * STEP_S;
        let ground = if self.wheels == WheelSpeeds::default() {
            self.wheels
        } else {
            WheelSpeeds {
                left_mm_s: self.wheels.left_mm_s * (1.0 + SLIP_SD * gaussian(&mut self.rng)),
                right_mm_s: self.wheels.right_mm_s * (1.0 + SLIP_SD * gaussian(&mut self.rng)),
            }
        };
        let next = self.pose.advance(ground, self.robot.wheel_base_mm, STEP_S);
        let clearance = |p: Pose| self.arena.clearance(p.point());
        // A move that does not bring the body closer to what it touches (sliding
        // along or backing away from a wall) is allowed even in contact.
        if self.arena.is_free(next.point(), self.robot.radius_mm)
            || (self.contact && clearance(next) >= clearance(self.pose) && clearance(next) > 0.0)
        {
            self.odometer_mm += self.pose.point().distance(next.point());
            self.pose = next;
            self.contact = false;
        } else {
            // A round body turns in place against a wall but does not pass through it.
            self.pose.theta_rad = next.theta_rad;
            if !self.contact {
                self.collisions += 1;
            }
            self.contact = true;
        }
        self.steps += 1;
    }

    /// Advances the clock by `seconds` (rounded to whole steps).
    pub fn run_for(&mut self, seconds: f64) {
        for _ in 0..(seconds / STEP_S).round() as u64 {
            self.step();
        }
    }

    /// The eight (or however many) proximity readings now, 0–1023.
    pub fn proximity(&mut self) -> Vec<u16> {
        let pose = self.pose;
        let World {
            arena, robot, rng, ..
        } = self;
        robot
            .sensors
            .iter()
            .map(|mount| {
                let (clean, distance_mm) = mapped_reading(arena, pose, mount);
                let value = if distance_mm <= robot.sensor_range_mm {
                    clean * (1.0 + READING_NOISE * rng.random_range(-1.0..1.0))
                } else {
                    NOISE_FLOOR * rng.random::<f64>()
                };
                value.round().clamp(0.0, 1023.0) as u16
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::Point;

    fn world(seed: u64) -> World {
        World::new(Arena::navigation(), RobotModel::khepera_ii(), seed).unwrap()
    }

    #[test]
    fn drives_straight_and_stops_at_the_box() {
        let mut w = world(1);
        w.set_wheels(WheelSpeeds {
            left_mm_s: 200.0,
            right_mm_s: 200.0,
        });
        w.run_for(0.3);
        assert!(
            w.pose().x_mm > 140.0 && w.pose().x_mm < 160.0,
            "{:?}",
            w.pose()
        );
        let far = w.proximity();
        w.run_for(2.0);
        // The box's face is at x = 250; the body (r = 35) stops just short of it.
        assert!(w.contact());
        assert_eq!(w.collisions(), 1);
        assert!(w.pose().x_mm < 250.0 - 35.0 && w.pose().x_mm > 250.0 - 35.0 - 3.0);
        let near = w.proximity();
        assert!(
            near[2] > 750 && near[3] > 750,
            "front sensors read {near:?}"
        );
        assert!(near[2] > far[2]);
    }

    #[test]
    fn dark_obstacles_read_lower() {
        let reading = |reflectivity: f64| {
            let mut arena = Arena::navigation();
            arena.obstacles[0].material.reflectivity = reflectivity;
            let mut w = World::new(arena, RobotModel::khepera_ii(), 1).unwrap();
            w.set_wheels(WheelSpeeds {
                left_mm_s: 200.0,
                right_mm_s: 200.0,
            });
            w.run_for(0.6);
            let n = w.proximity();
            f64::from(n[2] + n[3]) / 2.0
        };
        let (white, black) = (reading(1.0), reading(0.1));
        assert!(white > 200.0, "{white}");
        assert!((black / white - 0.1).abs() < 0.02, "{black} vs {white}");
    }

    #[test]
    fn odometry_drifts_from_the_truth() {
        let mut w = world(5);
        w.set_wheels(WheelSpeeds {
            left_mm_s: 100.0,
            right_mm_s: 100.0,
        });
        w.run_for(1.0);
        let [l, r] = w.wheel_travel_mm();
        // Both encoders counted the same turning, yet the body drifted.
        assert!((l - r).abs() < 1e-9);
        assert!(w.pose().theta_rad.abs() > 1e-6);
        assert!((w.odometer_mm() - l).abs() < 0.05 * l);
    }

    #[test]
    fn same_seed_same_run() {
        let run = |seed| {
            let mut w = world(seed);
            w.set_wheels(WheelSpeeds {
                left_mm_s: 150.0,
                right_mm_s: 90.0,
            });
            let mut readings = Vec::new();
            for _ in 0..50 {
                w.run_for(0.1);
                readings.push(w.proximity());
            }
            (w.pose(), readings)
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7).1, run(8).1);
    }

    #[test]
    fn a_start_inside_an_obstacle_is_refused() {
        let mut arena = Arena::navigation();
        arena.start.x_mm = 280.0;
        arena.start.y_mm = 100.0;
        let err = World::new(arena, RobotModel::khepera_ii(), 0).unwrap_err();
        assert!(err.to_string().contains("overlaps"), "{err}");
    }

    #[test]
    fn never_passes_through_walls() {
        let mut w = world(3);
        w.set_wheels(WheelSpeeds {
            left_mm_s: 800.0,
            right_mm_s: 700.0,
        });
        for _ in 0..2000 {
            w.step();
            assert!(w.arena().is_free(w.pose().point(), w.robot().radius_mm));
        }
        let _ = Point::default();
    }
}
#[cfg(test)]
mod turn_probe {
    use super::*;
    use vl_core::{Safety, Situation, Surroundings, Teleop, Told};
    #[test]
    fn probe() {
        for assist in [false, true] {
            for seed in 1..5 {
                let mut arena = Arena::load("open").unwrap();
                arena.start = Pose {
                    x_mm: 300.0,
                    y_mm: 300.0,
                    theta_rad: 0.0,
                };
                let robot = RobotModel::khepera_ii();
                let mut w = World::new(arena.clone(), robot.clone(), seed).unwrap();
                let s = Surroundings::new(&arena);
                let teleop = Teleop::default();
                let mut told = None;
                let mut max_turn = 0.0f64;
                for _ in 0..400 {
                    let prox = w.proximity();
                    let wanted = if assist {
                        let desired = teleop.velocity_for(&robot, 150.0, 0.0);
                        teleop
                            .assist(&robot, desired, teleop.sensor_field(&robot, &prox))
                            .wheels
                    } else {
                        WheelSpeeds {
                            left_mm_s: 150.0,
                            right_mm_s: 150.0,
                        }
                    };
                    let travel = w.wheel_travel_mm();
                    let sit = Situation {
                        pose: w.pose(),
                        wheels: w.wheels(),
                        told: Told::seen_from(told, travel),
                        proximity: &prox,
                    };
                    let g = Safety::default().guard(&robot, &s, sit, wanted);
                    told = Some((g.leash, travel));
                    w.drive(&g.leash, travel);
                    w.step();
                    max_turn = max_turn.max(w.pose().theta_rad.abs());
                }
                eprintln!(
                    "assist {assist} seed {seed}: final {:?} max turn {max_turn:.3} contacts {}",
                    w.pose(),
                    w.collisions()
                );
            }
        }
    }
}
