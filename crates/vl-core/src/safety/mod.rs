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

    /// How long after the reading a command reaches the wheels, s: the
    /// pose's age and the response's dead time.
    fn arrives_s(&self, robot: &RobotModel) -> f64 {
        robot.response.dead_time_s + self.delay_s.max(0.0)
    }

    /// The leash for `wheels` from `situation`, reaching the robot after
    /// the pose's age and the response's dead time.
    fn leash(&self, robot: &RobotModel, situation: Situation<'_>, wheels: WheelSpeeds) -> Leash {
        let arrives_s = self.arrives_s(robot);
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
        let arrives_s = self.arrives_s(robot);
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
mod tests;
