//! The safety layer: the Host's last word before every wheel command, from
//! whatever source (the operator's stick, a path follower, the assistance
//! of the potential fields). It lets through only motions after which the
//! robot can still stop before touching anything it knows of — the walls,
//! the mapped and virtual obstacles at its pose estimate, and what its
//! proximity sensors see — even if the Host never speaks again.
//!
//! Every motion leaves the layer as a [`Leash`]: each wheel's top speed and
//! how far it may turn, after which the robot's own position controller
//! stops it. A candidate is checked by running that motion out: the wheels
//! follow what they were last told until the leash reaches them, then each
//! follows its trapezoid to the end of its reach, through the robot's
//! [`SpeedResponse`](crate::SpeedResponse); the body must keep its margin
//! all the way. The layer keeps the turning part of the command and gives
//! up as little of the forward or backward speed as it must; when nothing
//! leashed stops clear, it stops the wheels at once (the speed controller
//! brakes harder than the profile). A round robot turning in place sweeps
//! nothing, and moving away from an obstacle is always allowed: inside the
//! margin, a command passes if it never brings the body nearer than it is.

use crate::{
    Arena, Leash, Nearest, Point, Pose, PositionControl, RobotModel, Shape, WheelSpeeds,
    ir_distance, ir_reading,
};

/// Braking is checked in steps this long, s: 2 mm at 1 m/s.
const CHECK_STEP_S: f64 = 0.002;
/// No stop takes longer than this, s.
const LONGEST_STOP_S: f64 = 5.0;
/// Bisection steps on the forward speed kept.
const BISECTIONS: u32 = 10;
/// A wheel this slow, mm/s, has stopped.
const STOPPED_MM_S: f64 = 1.0;
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
    /// motion being checked reaches them.
    pub told: Told,
    /// The proximity readings, one per sensor of the model.
    pub proximity: &'a [u16],
}

/// The last motion the robot was told.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Told {
    /// Stopped by the speed controller, or told nothing yet.
    #[default]
    Stop,
    /// A leash, each wheel's reach counted from `from_mm` of its travel
    /// (measured from where it was at this reading: its earlier reading's,
    /// so zero or behind).
    Leash { leash: Leash, from_mm: [f64; 2] },
}

impl Told {
    /// The last motion, `last` (a leash and the wheels' travel its reach
    /// counts from, or none: a stop), seen from a reading with the wheels
    /// at `travel_mm`.
    pub fn seen_from(last: Option<(Leash, [f64; 2])>, travel_mm: [f64; 2]) -> Told {
        match last {
            Some((leash, from)) if !leash.is_stop() => Told::Leash {
                leash,
                from_mm: [from[0] - travel_mm[0], from[1] - travel_mm[1]],
            },
            _ => Told::Stop,
        }
    }

    /// Its top speeds, mm/s.
    pub fn wheels(&self, robot: &RobotModel) -> WheelSpeeds {
        match self {
            Told::Stop => WheelSpeeds::default(),
            Told::Leash { leash, .. } => leash.wheels(robot),
        }
    }
}

/// What the layer lets through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guarded {
    /// The motion, as the robot is to be told it.
    pub leash: Leash,
    /// Its top speeds, mm/s.
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
    /// How long a leash must last before the next one extends it: the
    /// control period and its lateness, s. Longer leashes let the robot run
    /// at speed through a late period; the layer checks all of their length.
    pub hold_s: f64,
    /// How old the pose is by the time the command reaches the wheels, s:
    /// on a serial line, the reads after the odometry and the command's own
    /// exchange. Until then the wheels follow what they were last told.
    pub delay_s: f64,
}

impl Default for Safety {
    fn default() -> Self {
        Safety {
            margin_mm: 5.0,
            hold_s: 0.03,
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
    /// The motion nearest `wanted` after which the robot can still stop
    /// clear of everything it knows of, even left to itself.
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
        let leash = |wheels: WheelSpeeds| self.leash(robot, situation, wheels);
        let stops_clear = |leash: Leash| self.leash_clear(robot, situation, leash, body, floor);
        let asked = leash(wanted);
        let guarded = |leash: Leash| Guarded {
            limited: leash != asked,
            wheels: leash.wheels(robot),
            leash,
            clearance_mm: now,
        };
        if stops_clear(asked) {
            return guarded(asked);
        }
        // Keep the turn, give up forward speed: k scales the mean of the wheels.
        let mean = (wanted.left_mm_s + wanted.right_mm_s) / 2.0;
        let half_turn = (wanted.right_mm_s - wanted.left_mm_s) / 2.0;
        let scaled = |k: f64| {
            leash(WheelSpeeds {
                left_mm_s: k * mean - half_turn,
                right_mm_s: k * mean + half_turn,
            })
        };
        if !stops_clear(scaled(0.0)) {
            return guarded(Leash::STOP);
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

    /// The leash for `wheels` from `situation`, reaching the robot after
    /// the pose's age and the response's dead time.
    fn leash(&self, robot: &RobotModel, situation: Situation<'_>, wheels: WheelSpeeds) -> Leash {
        let arrives_s = robot.response.dead_time_s + self.delay_s.max(0.0);
        Leash::new(robot, wheels, self.hold_s, situation.wheels, arrives_s)
    }

    /// Whether every pose on the way from the robot's state in `situation`
    /// through `leash` to a stop keeps `body` (the room between the body
    /// and anything, which changes no faster than the robot's centre moves)
    /// at or above `floor`: what the wheels were told goes on until the
    /// leash reaches them, then each wheel follows its trapezoid to the end
    /// of its reach (a stop: the speed controller brakes). Room to spare
    /// lets the check skip ahead: with `slack` mm left, nothing can be
    /// touched before the centre has moved that far.
    fn leash_clear(
        &self,
        robot: &RobotModel,
        situation: Situation<'_>,
        leash: Leash,
        body: impl Fn(Pose) -> f64,
        floor: f64,
    ) -> bool {
        let arrives_s = robot.response.dead_time_s + self.delay_s.max(0.0);
        let response = &robot.response;
        let moves = leash.moves(robot, [0.0; 2]);
        let (mut pose, mut wheels, mut t) = (situation.pose, situation.wheels, 0.0);
        // The controllers lead the wheels by their lag: the wheels are
        // where their references are, at their speeds.
        let mut controls = [
            PositionControl::taking_over(0.0, wheels.left_mm_s),
            PositionControl::taking_over(0.0, wheels.right_mm_s),
        ];
        // Until the leash arrives, the last goes on; after a stop, the
        // speed controller has the wheels, and the position controller
        // takes them over as they are.
        let told = match situation.told {
            Told::Stop => None,
            Told::Leash { leash, from_mm } => Some(leash.moves(robot, from_mm)),
        };
        let mut taken_over = told.is_some();
        let mut travel = [0.0; 2];
        let mut slack = 0.0;
        let mut asked = [0.0; 2];
        while t < LONGEST_STOP_S {
            if !taken_over && t >= arrives_s {
                taken_over = true;
                let w = [wheels.left_mm_s, wheels.right_mm_s];
                controls = [0, 1].map(|i| PositionControl::taking_over(travel[i], w[i]));
            }
            for i in 0..2 {
                asked[i] = if t < arrives_s {
                    match &told {
                        Some(moves) => {
                            controls[i].step(&moves[i], travel[i], response, CHECK_STEP_S)
                        }
                        None => 0.0,
                    }
                } else if leash.is_stop() {
                    controls[i] = PositionControl::default();
                    0.0
                } else {
                    controls[i].step(&moves[i], travel[i], response, CHECK_STEP_S)
                };
            }
            let asked = WheelSpeeds {
                left_mm_s: asked[0],
                right_mm_s: asked[1],
            };
            let (before, was) = (pose.point(), wheels);
            (pose, wheels) = robot.respond(pose, wheels, asked, CHECK_STEP_S);
            travel[0] += (was.left_mm_s + wheels.left_mm_s) / 2.0 * CHECK_STEP_S;
            travel[1] += (was.right_mm_s + wheels.right_mm_s) / 2.0 * CHECK_STEP_S;
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
            let still = |v: f64| v.abs() < STOPPED_MM_S;
            let done = leash.is_stop()
                || (0..2).all(|i| {
                    controls[i].speed_mm_s == 0.0 && controls[i].reference_mm == moves[i].target_mm
                });
            if t >= arrives_s
                && done
                && still(asked.left_mm_s)
                && still(asked.right_mm_s)
                && still(wheels.left_mm_s)
                && still(wheels.right_mm_s)
            {
                return true;
            }
        }
        // A motion this long is not one to let go of the robot with.
        false
    }
}

#[cfg(test)]
mod tests {
    use super::tests_rig::Rig;
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

    /// Told to go on at `wheels`, from where the robot is.
    fn going(robot: &RobotModel, wheels: WheelSpeeds) -> Told {
        Told::Leash {
            leash: Leash::new(robot, wheels, 0.03, wheels, 0.0),
            from_mm: [0.0; 2],
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
            told: going(&robot, ahead(speed)),
            proximity: &[],
        };
        // At full speed the robot brakes by itself in 650 mm.
        let far = safety.guard(&robot, &s, facing_wall(700.0, 1016.0), ahead(1016.0));
        assert!(!far.limited, "{far:?}");
        // At 200 mm/s, 50 mm out: speeding up would not leave room to brake,
        // carrying on more slowly does.
        let near = safety.guard(&robot, &s, facing_wall(50.0, 200.0), ahead(1000.0));
        assert!(near.limited && near.wheels.left_mm_s > 0.0, "{near:?}");
        assert!(near.wheels.left_mm_s < 300.0, "{near:?}");
        // At 500 mm/s, 50 mm out, no leash stops clear: the wheels stop at once.
        let late = safety.guard(&robot, &s, facing_wall(50.0, 500.0), ahead(1000.0));
        assert!(late.leash.is_stop(), "{late:?}");
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
            told: Told::Stop,
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
            told: Told::Stop,
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
            told: Told::Stop,
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
                told: going(&robot, wheels),
                proximity: &[],
            };
            let g = safety.guard(&robot, &s, situation, WheelSpeeds { left_mm_s: wl, right_mm_s: wr });
            let now = arena.clearance(p) - robot.radius_mm;
            // The moving robot may already be past saving; then the layer
            // stops it and nothing more can be asked of it.
            prop_assume!(g.wheels != WheelSpeeds::default() || !g.limited);
            let floor = safety.margin_mm.min(now) - 1e-6;
            let exact = |pose: Pose| arena.clearance(pose.point()) - robot.radius_mm;
            prop_assert!(safety.leash_clear(&robot, situation, g.leash, exact, floor), "{:?} from {:?}", g, situation.pose);
        }

        /// Closed loop: a robot at rest anywhere free, driven by random
        /// full-speed commands that change every 0.2 s, each guarded and
        /// its leash followed by the wheels for a 10 ms control period,
        /// never touches anything — nor when, at any period, the Host
        /// freezes and the last leash runs out by itself.
        #[test]
        fn random_driving_through_the_layer_never_touches(
            fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
            commands in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 20),
            freeze in 0usize..400,
            arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
        ) {
            let standing = standing(arena, fx, fy);
            prop_assume!(standing.is_some());
            let (arena, robot, p) = standing.unwrap();
            let s = Surroundings::new(&arena);
            let safety = Safety::default();
            let mut rig = Rig::at(at(p.x_mm, p.y_mm, theta));
            let top = robot.max_wheel_speed_mm_s;
            let clear = |rig: &Rig| arena.clearance(rig.pose.point()) - robot.radius_mm;
            for tick in 0..400 {
                let (l, r) = commands[tick / 20];
                let wanted = WheelSpeeds { left_mm_s: l * top, right_mm_s: r * top };
                let situation = Situation { pose: rig.pose, wheels: rig.wheels, told: rig.told(), proximity: &[] };
                let g = safety.guard(&robot, &s, situation, wanted);
                rig.tell(&robot, g.leash, rig.travel);
                let steps = if tick == freeze { 5000 } else { 5 };
                for _ in 0..steps {
                    rig.step(&robot, 0.002);
                    prop_assert!(clear(&rig) > 0.0, "touched at {:?} on tick {} (frozen at {})", rig.pose, tick, freeze);
                }
                if tick == freeze {
                    prop_assert!(rig.wheels.left_mm_s.abs() < 1.0 && rig.wheels.right_mm_s.abs() < 1.0, "{:?}", rig.wheels);
                    break;
                }
            }
        }

        /// The same on a slow serial line: the pose is read at the start of
        /// each control period of up to 120 ms (a 9600-baud Khepera's reads),
        /// and the leash reaches the wheels up to a period later, the
        /// wheels meanwhile following the one before. Told the period and
        /// that delay, the layer still never lets the robot touch anything,
        /// frozen or not.
        #[test]
        fn random_driving_on_a_slow_line_never_touches(
            fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
            commands in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 8),
            period_steps in 5usize..60, delay_share in 0.0f64..1.0, freeze_share in 0.0f64..1.0,
            arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
        ) {
            let standing = standing(arena, fx, fy);
            prop_assume!(standing.is_some());
            let (arena, robot, p) = standing.unwrap();
            let s = Surroundings::new(&arena);
            let delay_steps = (delay_share * period_steps as f64) as usize;
            let safety = Safety {
                hold_s: 1.5 * period_steps as f64 * 0.002,
                delay_s: delay_steps as f64 * 0.002,
                ..Safety::default()
            };
            let mut rig = Rig::at(at(p.x_mm, p.y_mm, theta));
            let top = robot.max_wheel_speed_mm_s;
            let periods = 4000 / period_steps;
            let freeze = (freeze_share * periods as f64) as usize;
            let clear = |rig: &Rig| arena.clearance(rig.pose.point()) - robot.radius_mm;
            for tick in 0..periods {
                let (l, r) = commands[tick * commands.len() / periods];
                let wanted = WheelSpeeds { left_mm_s: l * top, right_mm_s: r * top };
                let situation = Situation { pose: rig.pose, wheels: rig.wheels, told: rig.told(), proximity: &[] };
                let g = safety.guard(&robot, &s, situation, wanted);
                let read_at = rig.travel;
                for _ in 0..delay_steps {
                    rig.step(&robot, 0.002);
                    prop_assert!(clear(&rig) > 0.0, "touched at {:?} in period {}", rig.pose, tick);
                }
                rig.tell(&robot, g.leash, read_at);
                let steps = if tick == freeze { 5000 } else { period_steps - delay_steps };
                for _ in 0..steps {
                    rig.step(&robot, 0.002);
                    prop_assert!(clear(&rig) > 0.0, "touched at {:?} in period {} (frozen at {})", rig.pose, tick, freeze);
                }
                if tick == freeze {
                    break;
                }
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
            told: Told::Stop,
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
        let gap = 200.0;
        let situation = Situation {
            pose: at(arena.width_mm - robot.radius_mm - gap, 300.0, 0.0),
            wheels: ahead(400.0),
            told: going(&robot, ahead(400.0)),
            proximity: &[],
        };
        let prompt = Safety::default().guard(&robot, &s, situation, ahead(800.0));
        assert!(prompt.wheels.left_mm_s > 400.0, "{prompt:?}");
        let late = Safety {
            delay_s: 0.1,
            hold_s: 0.1,
            ..Safety::default()
        }
        .guard(&robot, &s, situation, ahead(800.0));
        assert!(
            late.wheels.left_mm_s < prompt.wheels.left_mm_s,
            "{late:?} vs {prompt:?}"
        );
    }
}
#[cfg(test)]
mod tests_rig {
    use super::*;
    use crate::WheelMove;
    /// The robot as its firmware moves it: each wheel's controller on its
    /// leash's trapezoid (from where the wheel was when the robot was
    /// read), or braked by the speed controller.
    pub(super) struct Rig {
        pub(super) pose: Pose,
        pub(super) wheels: WheelSpeeds,
        pub(super) travel: [f64; 2],
        pub(super) controls: [PositionControl; 2],
        pub(super) moves: Option<[WheelMove; 2]>,
        /// The last leash and the travel its reach counts from.
        pub(super) leash: Option<(Leash, [f64; 2])>,
    }

    impl Rig {
        pub(super) fn at(pose: Pose) -> Rig {
            Rig {
                pose,
                wheels: WheelSpeeds::default(),
                travel: [0.0; 2],
                controls: [PositionControl::default(); 2],
                moves: None,
                leash: None,
            }
        }

        /// What the wheels were last told, seen from a reading now.
        pub(super) fn told(&self) -> Told {
            Told::seen_from(self.leash, self.travel)
        }

        pub(super) fn tell(&mut self, robot: &RobotModel, leash: Leash, read_at: [f64; 2]) {
            let was = self.moves;
            self.moves = (!leash.is_stop()).then(|| leash.moves(robot, read_at));
            self.leash = (!leash.is_stop()).then_some((leash, read_at));
            if was.is_none() {
                let w = [self.wheels.left_mm_s, self.wheels.right_mm_s];
                self.controls = [0, 1].map(|i| PositionControl::taking_over(self.travel[i], w[i]));
            }
        }

        pub(super) fn step(&mut self, robot: &RobotModel, dt: f64) {
            let mut asked = [0.0; 2];
            if let Some(moves) = self.moves {
                for i in 0..2 {
                    asked[i] =
                        self.controls[i].step(&moves[i], self.travel[i], &robot.response, dt);
                }
            }
            let asked = WheelSpeeds {
                left_mm_s: asked[0],
                right_mm_s: asked[1],
            };
            let was = self.wheels;
            (self.pose, self.wheels) = robot.respond(self.pose, self.wheels, asked, dt);
            self.travel[0] += (was.left_mm_s + self.wheels.left_mm_s) / 2.0 * dt;
            self.travel[1] += (was.right_mm_s + self.wheels.right_mm_s) / 2.0 * dt;
        }
    }
}
