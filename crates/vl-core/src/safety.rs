//! The safety layer: the Host's last word before every wheel command, from
//! whatever source (the operator's stick, a path follower, the assistance
//! of the potential fields). It lets through only commands after which the
//! robot can still stop before touching anything it knows of — the walls,
//! the mapped and virtual obstacles at its pose estimate, and what its
//! proximity sensors see — given how its wheels brake.
//!
//! A candidate command is checked by braking it out: the wheels follow it
//! for the reaction time (until the next command can act), then are told
//! to stop, both through the robot's [`SpeedResponse`](crate::SpeedResponse);
//! the body must keep its margin all the way. The layer keeps the turning
//! part of the command and gives up as little of the forward or backward
//! speed as it must. A round robot turning in place sweeps nothing, and
//! moving away from an obstacle is always allowed: inside the margin, a
//! command passes if it never brings the body nearer than it is.

use crate::{Arena, Nearest, Point, Pose, RobotModel, Shape, WheelSpeeds, ir_distance, ir_reading};

/// Braking is checked in steps this long, s: 2 mm at 1 m/s.
const CHECK_STEP_S: f64 = 0.002;
/// No stop takes longer than this, s.
const LONGEST_STOP_S: f64 = 5.0;
/// Bisection steps on the forward speed kept.
const BISECTIONS: u32 = 10;

/// What surrounds the robot: the arena's walls and obstacles, and a run's
/// virtual obstacles, measured exactly (a distance field on a grid would
/// be a lower bound that wobbles from cell to cell, so that backing away
/// from a wall could look like coming nearer). Distances are signed, so a
/// pose estimate already past a face still tells deeper from shallower.
/// Each virtual obstacle's bounding box is worked out once, when a run's
/// surroundings are made, so a check skips the ones far away.
#[derive(Debug, Clone)]
pub struct Surroundings {
    arena: Arena,
    virtual_obstacles: Vec<(Shape, Point, Point)>,
}

impl Surroundings {
    /// The arena's walls and obstacles.
    pub fn new(arena: &Arena) -> Surroundings {
        Surroundings {
            arena: arena.clone(),
            virtual_obstacles: Vec::new(),
        }
    }

    /// These surroundings with `shapes` added (a run's virtual obstacles).
    pub fn with(&self, shapes: &[Shape]) -> Surroundings {
        let mut more = self.clone();
        more.virtual_obstacles.extend(shapes.iter().map(|shape| {
            let (lo, hi) = shape.bounds();
            (shape.clone(), lo, hi)
        }));
        more
    }

    /// The signed distance from `p` to the nearest thing it could touch:
    /// negative beyond a wall or inside an obstacle.
    pub fn clearance(&self, p: Point) -> f64 {
        let mut nearest = self.arena.signed_clearance(p);
        for (shape, lo, hi) in &self.virtual_obstacles {
            // The box is no farther than the shape: a box farther than the
            // nearest thing yet cannot hold anything nearer.
            let dx = (lo.x_mm - p.x_mm).max(p.x_mm - hi.x_mm);
            let dy = (lo.y_mm - p.y_mm).max(p.y_mm - hi.y_mm);
            if dx.max(0.0).hypot(dy.max(0.0)) >= nearest {
                continue;
            }
            nearest = nearest.min(shape.signed_distance(p));
        }
        nearest
    }

    /// What is nearest `p`: a wall, one of the arena's obstacles or a
    /// virtual one (a closest approach is told by what it was to).
    pub fn nearest(&self, p: Point) -> Nearest {
        let obstacles = self.arena.obstacles.iter().map(|o| &o.shape);
        let virtuals = self.virtual_obstacles.iter().map(|(shape, ..)| shape);
        obstacles
            .enumerate()
            .map(|(i, s)| (s.signed_distance(p), Nearest::Obstacle(i)))
            .chain(
                virtuals
                    .enumerate()
                    .map(|(i, s)| (s.signed_distance(p), Nearest::VirtualObstacle(i))),
            )
            .fold(
                (self.arena.wall_clearance(p), Nearest::Wall),
                |best, next| if next.0 < best.0 { next } else { best },
            )
            .1
    }
}

/// The robot as the Host last read it.
#[derive(Debug, Clone, Copy)]
pub struct Situation<'a> {
    /// The pose estimate.
    pub pose: Pose,
    /// The wheels' measured speeds.
    pub wheels: WheelSpeeds,
    /// What the wheels were last told: they go on following it until the
    /// command being checked reaches them.
    pub told: WheelSpeeds,
    /// The proximity readings, one per sensor of the model.
    pub proximity: &'a [u16],
}

/// What the layer lets through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guarded {
    pub wheels: WheelSpeeds,
    /// Whether it had to change what was asked.
    pub limited: bool,
    /// How far the body is from the nearest thing it knows of now, mm.
    pub clearance_mm: f64,
}

/// The layer's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Safety {
    /// Room to keep between the body and anything, mm.
    pub margin_mm: f64,
    /// How long a command lasts before the next one can brake it: the
    /// control period and its lateness, s.
    pub reaction_s: f64,
    /// How old the pose is by the time the command reaches the wheels, s:
    /// on a serial line, the reads after the odometry and the command's own
    /// exchange. Until then the wheels follow what they were last told.
    pub delay_s: f64,
}

impl Default for Safety {
    fn default() -> Self {
        Safety {
            margin_mm: 5.0,
            reaction_s: 0.03,
            delay_s: 0.0,
        }
    }
}

/// Where each proximity reading says an obstacle is, in the arena frame.
/// A reading within the sensor's range is taken as a white surface (the
/// calibration's): a darker one is nearer than this, which is why the map
/// is checked too.
fn sensed(robot: &RobotModel, pose: Pose, proximity: &[u16]) -> Vec<Point> {
    let in_range = ir_reading(robot.sensor_range_mm);
    robot
        .sensors
        .iter()
        .zip(proximity)
        .filter(|(_, reading)| f64::from(**reading) > in_range)
        .filter_map(|(mount, &reading)| {
            let d = ir_distance(f64::from(reading))?;
            let (s, c) = mount.angle_rad.sin_cos();
            Some(pose.to_world(mount.x_mm + d * c, mount.y_mm + d * s))
        })
        .collect()
}

impl Safety {
    /// The command nearest `wanted` after which the robot can still stop
    /// clear of everything it knows of.
    pub fn guard(
        &self,
        robot: &RobotModel,
        surroundings: &Surroundings,
        situation: Situation<'_>,
        wanted: WheelSpeeds,
    ) -> Guarded {
        let wanted = robot.clamp(wanted);
        let points = sensed(robot, situation.pose, situation.proximity);
        let body = |pose: Pose| {
            let here = pose.point();
            let sensed = points
                .iter()
                .map(|p| here.distance(*p))
                .fold(f64::INFINITY, f64::min);
            surroundings.clearance(here).min(sensed) - robot.radius_mm
        };
        let now = body(situation.pose);
        // Inside the margin (or past a face) only what never comes nearer passes.
        let floor = self.margin_mm.min(now) - 1e-9;
        let stops_clear =
            |command: WheelSpeeds| self.brakes_clear(robot, situation, command, body, floor);
        let guarded = |wheels: WheelSpeeds| Guarded {
            limited: wheels != wanted,
            wheels,
            clearance_mm: now,
        };
        if stops_clear(wanted) {
            return guarded(wanted);
        }
        // Keep the turn, give up forward speed: k scales the mean of the wheels.
        let mean = (wanted.left_mm_s + wanted.right_mm_s) / 2.0;
        let half_turn = (wanted.right_mm_s - wanted.left_mm_s) / 2.0;
        let scaled = |k: f64| WheelSpeeds {
            left_mm_s: k * mean - half_turn,
            right_mm_s: k * mean + half_turn,
        };
        if !stops_clear(scaled(0.0)) {
            return guarded(WheelSpeeds::default());
        }
        let (mut clear, mut not) = (0.0, 1.0);
        for _ in 0..BISECTIONS {
            let k = (clear + not) / 2.0;
            if stops_clear(scaled(k)) {
                clear = k;
            } else {
                not = k;
            }
        }
        guarded(scaled(clear))
    }

    /// Whether every pose on the way from following `command` for the
    /// reaction time and then braking to a stop keeps `body` (the room
    /// between the body and anything, which changes no faster than the
    /// robot's centre moves) at or above `floor`. Room to spare lets the
    /// check skip ahead: with `slack` mm left, nothing can be touched before
    /// the centre has moved that far.
    fn brakes_clear(
        &self,
        robot: &RobotModel,
        situation: Situation<'_>,
        command: WheelSpeeds,
        body: impl Fn(Pose) -> f64,
        floor: f64,
    ) -> bool {
        let response = robot.response;
        let (mut pose, mut wheels, mut t) = (situation.pose, situation.wheels, 0.0);
        // Until the command reaches the wheels (and they answer), they go on
        // following what they were told.
        let dead = response.dead_time_s + self.delay_s.max(0.0);
        let mut slack = 0.0;
        while t < LONGEST_STOP_S {
            let target = if t < dead {
                situation.told
            } else if t < dead + self.reaction_s {
                command
            } else {
                WheelSpeeds::default()
            };
            let before = pose.point();
            (pose, wheels) = robot.respond(pose, wheels, target, CHECK_STEP_S);
            t += CHECK_STEP_S;
            slack -= before.distance(pose.point());
            // (A pose that is not a number leaves no slack, and fails.)
            if slack.is_nan() || slack <= 0.0 {
                let room = body(pose);
                if room.is_nan() || room < floor {
                    return false;
                }
                slack = room - floor;
            }
            if t >= dead + self.reaction_s && wheels == WheelSpeeds::default() {
                return true;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn open_arena() -> Arena {
        Arena::load("open").unwrap()
    }

    fn at(x_mm: f64, y_mm: f64, theta_rad: f64) -> Pose {
        Pose {
            x_mm,
            y_mm,
            theta_rad,
        }
    }

    fn ahead(v: f64) -> WheelSpeeds {
        WheelSpeeds {
            left_mm_s: v,
            right_mm_s: v,
        }
    }

    #[test]
    fn full_speed_at_a_wall_slows_in_time_and_backing_off_is_free() {
        let arena = open_arena();
        let robot = RobotModel::khepera_ii();
        let s = Surroundings::new(&arena);
        let safety = Safety::default();
        let facing_wall = |gap: f64, speed: f64| Situation {
            pose: at(arena.width_mm - robot.radius_mm - gap, 300.0, 0.0),
            wheels: ahead(speed),
            told: ahead(speed),
            proximity: &[],
        };
        let far = safety.guard(&robot, &s, facing_wall(400.0, 1000.0), ahead(1000.0));
        assert!(!far.limited, "{far:?}");
        // At 500 mm/s, 50 mm out: speeding up would not leave room to brake,
        // carrying on more slowly does.
        let near = safety.guard(&robot, &s, facing_wall(50.0, 500.0), ahead(1000.0));
        assert!(near.limited && near.wheels.left_mm_s > 0.0, "{near:?}");
        assert!(near.wheels.left_mm_s < 1000.0);
        let facing_wall = |gap: f64| facing_wall(gap, 0.0);
        let touching = safety.guard(&robot, &s, facing_wall(1.0), ahead(300.0));
        assert_eq!(touching.wheels, WheelSpeeds::default(), "{touching:?}");
        let back = safety.guard(&robot, &s, facing_wall(1.0), ahead(-300.0));
        assert!(!back.limited, "moving away is always allowed: {back:?}");
        let spin = WheelSpeeds {
            left_mm_s: -200.0,
            right_mm_s: 200.0,
        };
        assert!(!safety.guard(&robot, &s, facing_wall(1.0), spin).limited);
    }

    #[test]
    fn virtual_obstacles_are_walls_to_the_layer() {
        let arena = open_arena();
        let robot = RobotModel::khepera_ii();
        let block = Shape::Circle {
            x_mm: 400.0,
            y_mm: 300.0,
            radius_mm: 20.0,
        };
        let s = Surroundings::new(&arena).with(std::slice::from_ref(&block));
        let p = Point {
            x_mm: 400.0 - 20.0 - robot.radius_mm - 6.0,
            y_mm: 300.0,
        };
        assert_eq!(s.clearance(p), block.distance(p));
        let situation = Situation {
            pose: at(p.x_mm, p.y_mm, 0.0),
            wheels: WheelSpeeds::default(),
            told: WheelSpeeds::default(),
            proximity: &[],
        };
        let g = Safety::default().guard(&robot, &s, situation, ahead(500.0));
        assert!(g.limited && g.wheels.left_mm_s < 100.0, "{g:?}");
    }

    #[test]
    fn what_the_sensors_see_counts_as_an_obstacle() {
        let arena = open_arena();
        let robot = RobotModel::khepera_ii();
        let s = Surroundings::new(&arena);
        // The two front sensors see something 10 mm ahead that no map shows.
        let mut proximity = vec![0; 8];
        proximity[2] = ir_reading(10.0) as u16;
        proximity[3] = ir_reading(10.0) as u16;
        let situation = Situation {
            pose: at(300.0, 300.0, 0.0),
            wheels: WheelSpeeds::default(),
            told: WheelSpeeds::default(),
            proximity: &proximity,
        };
        let g = Safety::default().guard(&robot, &s, situation, ahead(500.0));
        assert!(g.wheels.left_mm_s < 1.0, "{g:?}");
    }

    #[test]
    fn numbers_that_are_not_speeds_stop_the_robot() {
        let arena = open_arena();
        let robot = RobotModel::khepera_ii();
        let s = Surroundings::new(&arena);
        let situation = Situation {
            pose: at(300.0, 300.0, 0.0),
            wheels: WheelSpeeds::default(),
            told: WheelSpeeds::default(),
            proximity: &[],
        };
        let nan = WheelSpeeds {
            left_mm_s: f64::NAN,
            right_mm_s: 1.0,
        };
        let g = Safety::default().guard(&robot, &s, situation, nan);
        assert_eq!(g.wheels, WheelSpeeds::default());
    }

    /// A shipped arena and the point (fx, fy) of the way across it, where
    /// the Khepera II stands clear of everything, if it does.
    fn standing(name: &str, fx: f64, fy: f64) -> Option<(Arena, RobotModel, Point)> {
        let arena = Arena::load(name).unwrap();
        let robot = RobotModel::khepera_ii();
        let p = Point {
            x_mm: fx * arena.width_mm,
            y_mm: fy * arena.height_mm,
        };
        arena
            .is_free(p, robot.radius_mm + 1.0)
            .then_some((arena, robot, p))
    }

    proptest! {
        /// Whatever is asked, wherever the robot is and however fast it
        /// goes, driving the guarded command and then braking never brings
        /// the body nearer than the margin, or nearer than it already was.
        #[test]
        fn guarded_commands_always_stop_in_time(
            fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
            vl in -1100.0f64..1100.0, vr in -1100.0f64..1100.0,
            wl in -1100.0f64..1100.0, wr in -1100.0f64..1100.0,
            arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
        ) {
            let standing = standing(arena, fx, fy);
            prop_assume!(standing.is_some());
            let (arena, robot, p) = standing.unwrap();
            let s = Surroundings::new(&arena);
            let safety = Safety::default();
            let wheels = robot.clamp(WheelSpeeds { left_mm_s: vl, right_mm_s: vr });
            let situation = Situation {
                pose: at(p.x_mm, p.y_mm, theta),
                wheels,
                told: wheels,
                proximity: &[],
            };
            let g = safety.guard(&robot, &s, situation, WheelSpeeds { left_mm_s: wl, right_mm_s: wr });
            let now = arena.clearance(p) - robot.radius_mm;
            // The moving robot may already be past saving; then the layer
            // stops it and nothing more can be asked of it.
            prop_assume!(g.wheels != WheelSpeeds::default() || !g.limited);
            let floor = safety.margin_mm.min(now) - 1e-6;
            let exact = |pose: Pose| arena.clearance(pose.point()) - robot.radius_mm;
            prop_assert!(safety.brakes_clear(&robot, situation, g.wheels, exact, floor), "{:?} from {:?}", g, situation.pose);
        }

        /// Closed loop: a robot at rest anywhere free, driven for 4 s by
        /// random full-speed commands that change every 0.2 s, each guarded
        /// and then followed by its wheels for a 10 ms control period,
        /// never touches anything.
        #[test]
        fn random_driving_through_the_layer_never_touches(
            fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
            commands in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 20),
            arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
        ) {
            let standing = standing(arena, fx, fy);
            prop_assume!(standing.is_some());
            let (arena, robot, p) = standing.unwrap();
            let s = Surroundings::new(&arena);
            let safety = Safety::default();
            let (mut pose, mut wheels) = (at(p.x_mm, p.y_mm, theta), WheelSpeeds::default());
            let mut told = WheelSpeeds::default();
            let top = robot.max_wheel_speed_mm_s;
            let mut closest = f64::INFINITY;
            for tick in 0..400 {
                let (l, r) = commands[tick / 20];
                let wanted = WheelSpeeds { left_mm_s: l * top, right_mm_s: r * top };
                let situation = Situation { pose, wheels, told, proximity: &[] };
                let command = safety.guard(&robot, &s, situation, wanted).wheels;
                told = command;
                for _ in 0..5 {
                    let next = WheelSpeeds {
                        left_mm_s: robot.response.step(wheels.left_mm_s, command.left_mm_s, 0.002),
                        right_mm_s: robot.response.step(wheels.right_mm_s, command.right_mm_s, 0.002),
                    };
                    pose = pose.advance(next, robot.wheel_base_mm, 0.002);
                    wheels = next;
                    let body = arena.clearance(pose.point()) - robot.radius_mm;
                    closest = closest.min(body);
                    prop_assert!(body > 0.0, "touched at {:?} on tick {}", pose, tick);
                }
            }
            prop_assert!(closest > 0.0);
        }

        /// The same on a slow serial line: the pose is read at the start of
        /// each control period of up to 120 ms (a 9600-baud Khepera's reads),
        /// and the command reaches the wheels up to a period later, the
        /// wheels meanwhile following the one before. Told the period and
        /// that delay, the layer still never lets the robot touch anything.
        #[test]
        fn random_driving_on_a_slow_line_never_touches(
            fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
            commands in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 8),
            period_steps in 5usize..60, delay_share in 0.0f64..1.0,
            arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
        ) {
            let standing = standing(arena, fx, fy);
            prop_assume!(standing.is_some());
            let (arena, robot, p) = standing.unwrap();
            let s = Surroundings::new(&arena);
            let delay_steps = (delay_share * period_steps as f64) as usize;
            let safety = Safety {
                reaction_s: period_steps as f64 * 0.002,
                delay_s: delay_steps as f64 * 0.002,
                ..Safety::default()
            };
            let (mut pose, mut wheels) = (at(p.x_mm, p.y_mm, theta), WheelSpeeds::default());
            let mut told = WheelSpeeds::default();
            let top = robot.max_wheel_speed_mm_s;
            let periods = 4000 / period_steps;
            for tick in 0..periods {
                let (l, r) = commands[tick * commands.len() / periods];
                let wanted = WheelSpeeds { left_mm_s: l * top, right_mm_s: r * top };
                let situation = Situation { pose, wheels, told, proximity: &[] };
                let command = safety.guard(&robot, &s, situation, wanted).wheels;
                for step in 0..period_steps {
                    let target = if step < delay_steps { told } else { command };
                    (pose, wheels) = robot.respond(pose, wheels, target, 0.002);
                    let body = arena.clearance(pose.point()) - robot.radius_mm;
                    prop_assert!(body > 0.0, "touched at {:?} in period {}", pose, tick);
                }
                told = command;
            }
        }
    }

    #[test]
    fn past_a_face_only_coming_out_passes() {
        let arena = open_arena();
        let robot = RobotModel::khepera_ii();
        let s = Surroundings::new(&arena);
        // The estimate says the body is 20 mm into the east wall.
        let situation = Situation {
            pose: at(arena.width_mm - robot.radius_mm + 20.0, 300.0, 0.0),
            wheels: WheelSpeeds::default(),
            told: WheelSpeeds::default(),
            proximity: &[],
        };
        let safety = Safety::default();
        let deeper = safety.guard(&robot, &s, situation, ahead(1000.0));
        assert_eq!(deeper.wheels, WheelSpeeds::default(), "{deeper:?}");
        assert!(deeper.clearance_mm < -19.0, "{deeper:?}");
        let out = safety.guard(&robot, &s, situation, ahead(-300.0));
        assert!(!out.limited, "{out:?}");
    }

    #[test]
    fn a_late_command_brakes_earlier() {
        let arena = open_arena();
        let robot = RobotModel::khepera_ii();
        let s = Surroundings::new(&arena);
        let gap = 120.0;
        let situation = Situation {
            pose: at(arena.width_mm - robot.radius_mm - gap, 300.0, 0.0),
            wheels: ahead(800.0),
            told: ahead(800.0),
            proximity: &[],
        };
        let prompt = Safety::default().guard(&robot, &s, situation, ahead(800.0));
        let late = Safety {
            delay_s: 0.1,
            reaction_s: 0.1,
            ..Safety::default()
        }
        .guard(&robot, &s, situation, ahead(800.0));
        assert!(
            late.wheels.left_mm_s < prompt.wheels.left_mm_s,
            "{late:?} vs {prompt:?}"
        );
    }
}
