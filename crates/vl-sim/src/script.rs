//! Runs of the simulator, scripted or following a planned path, with a
//! fingerprint of everything that happened, so "same seed, same inputs,
//! same trace" can be checked anywhere.

use serde::Serialize;
use thiserror::Error;
use vl_core::{
    ArenaPlanError, Definition, Follower, Goal, Point, Pose, Steer, WheelSpeeds, plan_route,
};
use vl_report::table::{Report, Table};

use crate::world::{STEP_S, World};

/// How often the proximity sensors are read (the Khepera's IR period).
const SENSE_EVERY_STEPS: u64 = 2;

/// Wheel speeds from given times on: `(t_s, speeds)`, in time order.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelSchedule(pub Vec<(f64, WheelSpeeds)>);

#[derive(Debug, Error, PartialEq, Eq)]
pub enum WheelScheduleError {
    #[error("script line {line}: expected 't_s left_mm_s right_mm_s', got '{text}'")]
    Syntax { line: usize, text: String },
    #[error("script line {line}: time {t} s comes before the previous line's")]
    OutOfOrder { line: usize, t: String },
}

impl WheelSchedule {
    /// Parses lines of `t_s left_mm_s right_mm_s`; `#` starts a comment.
    pub fn parse(text: &str) -> Result<WheelSchedule, WheelScheduleError> {
        let mut steps: Vec<(f64, WheelSpeeds)> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let numbers: Option<Vec<f64>> = line
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|w| !w.is_empty())
                .map(|w| w.parse().ok().filter(|v: &f64| v.is_finite()))
                .collect();
            let Some(&[t, left, right]) = numbers.as_deref() else {
                return Err(WheelScheduleError::Syntax {
                    line: i + 1,
                    text: raw.to_owned(),
                });
            };
            if steps.last().is_some_and(|(prev, _)| t < *prev) {
                return Err(WheelScheduleError::OutOfOrder {
                    line: i + 1,
                    t: t.to_string(),
                });
            }
            steps.push((
                t,
                WheelSpeeds {
                    left_mm_s: left,
                    right_mm_s: right,
                },
            ));
        }
        Ok(WheelSchedule(steps))
    }

    /// The speeds in force at `t_s`.
    fn at(&self, t_s: f64) -> WheelSpeeds {
        self.0
            .iter()
            .take_while(|(t, _)| *t <= t_s + 1e-9)
            .last()
            .map(|(_, w)| *w)
            .unwrap_or_default()
    }
}

/// What drives the robot during a run.
#[derive(Debug, Clone)]
pub enum Driver {
    /// Wheel speeds at given times.
    WheelSchedule(WheelSchedule),
    /// A path to follow; the run ends when the robot arrives.
    Path(Follower),
    /// Nothing: the robot stays put.
    Idle,
}

/// How long an idle run, or a scripted one past its last line, lasts
/// unless told otherwise, s.
const SCRIPT_TAIL_S: f64 = 10.0;

impl Driver {
    /// A follower of the path a Guest would plan from the robot to `goal`
    /// (the arena's suggested one when absent); idle when there is neither.
    pub fn to_goal(world: &World, goal: Option<Point>) -> Result<Driver, ArenaPlanError> {
        let Some(goal) = goal.or(world.arena().goal) else {
            return Ok(Driver::Idle);
        };
        let plan = plan_route(world.arena(), &[], world.robot(), world.pose(), goal)?;
        let definition = Definition {
            goal: Some(Goal::at(goal)),
            path: plan.points(),
            ..Definition::default()
        };
        let follower = Follower::for_definition(&definition).expect("a plan has samples");
        Ok(Driver::Path(follower))
    }

    /// How long a run needs: twice the path's time at cruising speed plus
    /// turning room; a script's last line and then [`SCRIPT_TAIL_S`].
    pub fn duration_s(&self) -> f64 {
        match self {
            Driver::Path(follower) => 2.0 * follower.expected_seconds(None) + 5.0,
            Driver::WheelSchedule(script) => {
                script.0.last().map_or(0.0, |&(t, _)| t.max(0.0)) + SCRIPT_TAIL_S
            }
            Driver::Idle => SCRIPT_TAIL_S,
        }
    }
}

/// What a run did.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RunReport {
    pub sim_seconds: f64,
    pub final_pose: Pose,
    pub collisions: u64,
    pub distance_mm: f64,
    /// How well a followed path was kept to.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub following: Option<Tracking>,
    /// FNV-1a over every step's pose and every sensor reading, as hex.
    pub trace_hash: String,
}

/// How far the robot's true position strayed from the path it followed.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Tracking {
    pub reached_goal: bool,
    /// Mean and largest distance from the path, sampled every step.
    pub mean_error_mm: f64,
    pub max_error_mm: f64,
}

/// 64-bit FNV-1a, fed the exact bits of the trace.
struct Fnv(u64);

impl Fnv {
    fn feed(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

/// Runs `world` for up to `seconds` as `driver` says.
pub fn run(world: &mut World, driver: &mut Driver, seconds: f64) -> RunReport {
    let mut trace = Fnv(0xcbf2_9ce4_8422_2325);
    let steps = (seconds / STEP_S).round() as u64;
    let mut proximity = world.proximity();
    let (mut error_sum, mut error_max, mut arrived) = (0.0, 0.0f64, false);
    let mut followed = 0u64;
    for step in 0..steps {
        if step % SENSE_EVERY_STEPS == 0 {
            proximity = world.proximity();
            for v in &proximity {
                trace.feed(&v.to_le_bytes());
            }
        }
        let wheels = match driver {
            Driver::WheelSchedule(script) => script.at(world.time_s()),
            Driver::Path(follower) => {
                let steer = follower.step(world.robot(), world.pose(), &proximity);
                arrived = steer == Steer::Arrived;
                steer.wheels()
            }
            Driver::Idle => WheelSpeeds::default(),
        };
        if arrived {
            world.set_wheels(wheels);
            break;
        }
        world.set_wheels(wheels);
        world.step();
        let p = world.pose();
        for v in [p.x_mm, p.y_mm, p.theta_rad] {
            trace.feed(&v.to_bits().to_le_bytes());
        }
        if let Driver::Path(follower) = driver {
            let e = follower.distance_to_path(p.point());
            error_sum += e;
            error_max = error_max.max(e);
            followed += 1;
        }
    }
    RunReport {
        sim_seconds: world.time_s(),
        final_pose: world.pose(),
        collisions: world.collisions(),
        distance_mm: world.odometer_mm(),
        following: matches!(driver, Driver::Path(_)).then(|| Tracking {
            reached_goal: arrived,
            mean_error_mm: error_sum / followed.max(1) as f64,
            max_error_mm: error_max,
        }),
        trace_hash: format!("{:016x}", trace.0),
    }
}

impl Report for RunReport {
    fn table(&self) -> Table {
        let p = self.final_pose;
        let mut rows = vec![
            ("simulated", format!("{:.2} s", self.sim_seconds)),
            (
                "final pose",
                format!(
                    "({:.1}, {:.1}) mm, {:.1}°",
                    p.x_mm,
                    p.y_mm,
                    p.theta_rad.to_degrees()
                ),
            ),
            ("distance", format!("{:.0} mm", self.distance_mm)),
        ];
        if let Some(t) = self.following {
            rows.push((
                "goal",
                format!(
                    "{} (path kept to within {:.1} mm on average, {:.1} mm at worst)",
                    if t.reached_goal {
                        "reached"
                    } else {
                        "not reached"
                    },
                    t.mean_error_mm,
                    t.max_error_mm
                ),
            ));
        }
        rows.push(("collisions", self.collisions.to_string()));
        rows.push(("trace hash", self.trace_hash.clone()));
        Table::pairs(rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Arena, RobotModel};

    fn world(seed: u64) -> World {
        World::new(Arena::navigation(), RobotModel::khepera_ii(), seed).unwrap()
    }

    #[test]
    fn same_seed_same_trace_other_seed_other_trace() {
        let path = |w: &World| Driver::to_goal(w, None).unwrap();
        let (mut w3, mut w3b, mut w4) = (world(3), world(3), world(4));
        let (mut p3, mut p3b, mut p4) = (path(&w3), path(&w3b), path(&w4));
        let a = run(&mut w3, &mut p3, 5.0);
        let b = run(&mut w3b, &mut p3b, 5.0);
        let c = run(&mut w4, &mut p4, 5.0);
        assert_eq!(a, b);
        assert_ne!(a.trace_hash, c.trace_hash);
    }

    #[test]
    fn runs_last_as_long_as_their_driver_needs() {
        let w = world(1);
        let follow = Driver::to_goal(&w, None).unwrap();
        assert!(
            (10.0..30.0).contains(&follow.duration_s()),
            "{}",
            follow.duration_s()
        );
        let script = Driver::WheelSchedule(WheelSchedule::parse("0 10 10\n12 0 0").unwrap());
        assert_eq!(script.duration_s(), 22.0);
        assert!(matches!(
            Driver::to_goal(
                &w,
                Some(Point {
                    x_mm: 280.0,
                    y_mm: 100.0
                })
            ),
            Err(ArenaPlanError::NoPath(_))
        ));
    }

    #[test]
    fn scripts_parse_and_drive() {
        let script = WheelSchedule::parse("# a turn\n0 100 100\n1.0, 50, 150\n").unwrap();
        assert_eq!(script.at(0.5).left_mm_s, 100.0);
        assert_eq!(script.at(1.5).right_mm_s, 150.0);
        let report = run(
            &mut world(1),
            &mut Driver::WheelSchedule(script.clone()),
            2.0,
        );
        assert!(report.distance_mm > 100.0, "{report:?}");
        assert!(
            report.final_pose.theta_rad > 0.5,
            "the second line turns it left: {report:?}"
        );
        assert_eq!(
            WheelSchedule::parse("0 1\n"),
            Err(WheelScheduleError::Syntax {
                line: 1,
                text: "0 1".into()
            })
        );
        assert!(matches!(
            WheelSchedule::parse("2 0 0\n1 0 0"),
            Err(WheelScheduleError::OutOfOrder { line: 2, .. })
        ));
    }
}
