//! A navigation definition tried on the lab's twin before the robot moves
//! (issue 29): the same follower and the same safety layer as the Host's
//! run, on the simulated robot of the same model in the lab's arena with
//! the definition's virtual obstacles, over a few seeds of sensor and
//! wheel noise, far faster than real time. What it foresees — whether and
//! when the goal is reached, the closest approach and where, contacts, how
//! long the safety layer holds the robot back and the wheels saturate, how
//! well the path is kept — is what a lab can refuse a definition for
//! before anything moves, and what a run is later compared with.

use serde::Serialize;
use thiserror::Error;
use vl_core::table::{Report, Table};
use vl_core::{
    Arena, Definition, Follower, Point, Pose, RobotModel, Safety, Situation, Steer, Surroundings,
    WheelSpeeds,
};

use crate::world::{STEP_S, SimError, World};

/// How often the proximity sensors are read, in steps: the Khepera's IR
/// period, as the Host reads them.
const SENSE_EVERY_STEPS: u64 = 2;
/// A foreseen path keeps a point this often, in steps: 10 a second.
const PATH_EVERY_STEPS: u64 = 10;
/// No forecast runs longer than this, s, whatever the definition says.
pub const LONGEST_S: f64 = 600.0;

/// What to forecast.
#[derive(Debug, Clone, Copy)]
pub struct Forecasting<'a> {
    pub arena: &'a Arena,
    pub robot: &'a RobotModel,
    /// Where the robot is when the run would start.
    pub start: Pose,
    pub definition: &'a Definition,
    /// One forecast run per seed of the simulator's noise.
    pub seeds: &'a [u64],
}

#[derive(Debug, Error, PartialEq)]
pub enum ForecastError {
    #[error("the definition has no path to follow: only a navigation run with a path is forecast")]
    NoPath,
    #[error("no seeds to forecast with")]
    NoSeeds,
    #[error("{0}")]
    World(#[from] SimError),
}

/// One seed's forecast run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeedRun {
    pub seed: u64,
    pub reached_goal: bool,
    /// Until the goal, or the run's time limit.
    pub seconds: f64,
    /// The least room between the body and anything (walls, obstacles,
    /// virtual obstacles), mm, and where the robot was then.
    pub closest_mm: f64,
    pub closest_at: Point,
    pub collisions: u64,
    /// How long the safety layer changed what the follower asked, s.
    pub held_back_s: f64,
    /// How long the follower asked more of a wheel than it (or the
    /// definition's cap) allows, s.
    pub saturated_s: f64,
    /// Mean distance from the defined path, mm.
    pub mean_error_mm: f64,
    /// Where the robot went, ten points a second.
    pub path: Vec<Point>,
}

/// A definition's forecast: one run per seed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Forecast {
    pub runs: Vec<SeedRun>,
}

/// Forecasts `what`: one run per seed.
pub fn forecast(what: Forecasting<'_>) -> Result<Forecast, ForecastError> {
    if what.seeds.is_empty() {
        return Err(ForecastError::NoSeeds);
    }
    let runs = what
        .seeds
        .iter()
        .map(|&seed| run(&what, seed))
        .collect::<Result<_, _>>()?;
    Ok(Forecast { runs })
}

/// One forecast run, as the Host's control loop would drive it.
fn run(what: &Forecasting<'_>, seed: u64) -> Result<SeedRun, ForecastError> {
    let Forecasting {
        robot, definition, ..
    } = *what;
    let mut follower = Follower::for_definition(definition).ok_or(ForecastError::NoPath)?;
    let arena = Arena {
        start: what.start,
        ..what.arena.clone()
    };
    let surroundings = Surroundings::new(&arena).with(&definition.virtual_obstacles);
    let mut world = World::new(arena, robot.clone(), seed)?;
    let limit_s = definition
        .time_limit_s
        .unwrap_or(2.0 * follower.expected_seconds() + 5.0)
        .min(LONGEST_S);
    let safety = Safety::default();
    let room = |p: Point| surroundings.clearance(p) - robot.radius_mm;
    let mut told = WheelSpeeds::default();
    let mut proximity = world.proximity();
    let mut out = SeedRun {
        seed,
        reached_goal: false,
        seconds: 0.0,
        closest_mm: room(what.start.point()),
        closest_at: what.start.point(),
        collisions: 0,
        held_back_s: 0.0,
        saturated_s: 0.0,
        mean_error_mm: 0.0,
        path: vec![what.start.point()],
    };
    let (mut error_sum, mut steps) = (0.0, 0u64);
    while world.time_s() < limit_s {
        if steps % SENSE_EVERY_STEPS == 0 {
            proximity = world.proximity();
        }
        let pose = world.pose();
        let Steer::Drive(asked) = follower.step(robot, pose, &proximity) else {
            out.reached_goal = true;
            break;
        };
        let wanted = definition.capped(robot, asked);
        if wanted != asked {
            out.saturated_s += STEP_S;
        }
        let situation = Situation {
            pose,
            wheels: world.wheels(),
            told,
            proximity: &proximity,
        };
        let guarded = safety.guard(robot, &surroundings, situation, wanted);
        if guarded.limited {
            out.held_back_s += STEP_S;
        }
        told = guarded.wheels;
        world.set_wheels(told);
        world.step();
        steps += 1;
        let here = world.pose().point();
        let room = room(here);
        if room < out.closest_mm {
            (out.closest_mm, out.closest_at) = (room, here);
        }
        error_sum += follower.distance_to_path(here);
        if steps % PATH_EVERY_STEPS == 0 {
            out.path.push(here);
        }
    }
    out.path.push(world.pose().point());
    out.seconds = world.time_s();
    out.collisions = world.collisions();
    out.mean_error_mm = error_sum / steps.max(1) as f64;
    Ok(out)
}

/// The least, mean and most of some figure over the seeds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    pub least: f64,
    pub mean: f64,
    pub most: f64,
}

impl Spread {
    fn of(values: impl Iterator<Item = f64>) -> Spread {
        let (mut least, mut most, mut sum, mut n) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0);
        for v in values {
            (least, most, sum, n) = (least.min(v), most.max(v), sum + v, n + 1);
        }
        Spread {
            least,
            mean: sum / f64::from(n.max(1)),
            most,
        }
    }
}

impl Forecast {
    /// How many seeds reach the goal.
    pub fn reached(&self) -> usize {
        self.runs.iter().filter(|r| r.reached_goal).count()
    }

    /// The time to the goal over the seeds that reach it.
    pub fn seconds(&self) -> Spread {
        Spread::of(
            self.runs
                .iter()
                .filter(|r| r.reached_goal)
                .map(|r| r.seconds),
        )
    }

    /// The closest approach over every seed, and where.
    pub fn closest(&self) -> (f64, Point) {
        self.runs
            .iter()
            .map(|r| (r.closest_mm, r.closest_at))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((f64::INFINITY, Point::default()))
    }

    pub fn collisions(&self) -> u64 {
        self.runs.iter().map(|r| r.collisions).sum()
    }

    pub fn held_back_s(&self) -> Spread {
        Spread::of(self.runs.iter().map(|r| r.held_back_s))
    }

    pub fn saturated_s(&self) -> Spread {
        Spread::of(self.runs.iter().map(|r| r.saturated_s))
    }

    pub fn mean_error_mm(&self) -> Spread {
        Spread::of(self.runs.iter().map(|r| r.mean_error_mm))
    }
}

impl Report for Forecast {
    fn table(&self) -> Table {
        let spread = |s: Spread, unit: &str| {
            format!(
                "{:.1} {unit} (from {:.1} to {:.1})",
                s.mean, s.least, s.most
            )
        };
        let (closest, at) = self.closest();
        Table::pairs([
            (
                "reaches the goal",
                format!("{} of {} seeds", self.reached(), self.runs.len()),
            ),
            (
                "time to the goal",
                match self.reached() {
                    0 => "never".to_owned(),
                    _ => spread(self.seconds(), "s"),
                },
            ),
            (
                "closest approach",
                format!("{closest:.1} mm, at ({:.0}, {:.0}) mm", at.x_mm, at.y_mm),
            ),
            ("contacts", self.collisions().to_string()),
            ("held back", spread(self.held_back_s(), "s")),
            ("wheels saturated", spread(self.saturated_s(), "s")),
            ("off the path", spread(self.mean_error_mm(), "mm")),
        ])
        .title("the definition, tried on the lab's twin:")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use vl_core::{Goal, Shape, plan_route};

    /// The navigation arena's own goal, planned from its start.
    fn planned() -> (Arena, RobotModel, Definition) {
        let arena = Arena::navigation();
        let robot = RobotModel::khepera_ii();
        let goal = arena.goal.expect("the navigation arena has a goal");
        let plan = plan_route(&arena, &[], &robot, arena.start, goal).unwrap();
        let definition = Definition {
            goal: Some(Goal::at(goal)),
            path: plan.points(),
            ..Definition::default()
        };
        (arena, robot, definition)
    }

    fn of(arena: &Arena, robot: &RobotModel, definition: &Definition, seeds: &[u64]) -> Forecast {
        forecast(Forecasting {
            arena,
            robot,
            start: arena.start,
            definition,
            seeds,
        })
        .unwrap()
    }

    #[test]
    fn a_planned_path_is_foreseen_to_reach_its_goal_clear_of_everything() {
        let (arena, robot, definition) = planned();
        let f = of(&arena, &robot, &definition, &[1, 2, 3]);
        println!("{}", f.table());
        assert_eq!(f.reached(), 3, "{f:?}");
        assert_eq!(f.collisions(), 0);
        let (closest, _) = f.closest();
        assert!(closest > 0.0, "{closest}");
        let t = f.seconds();
        assert!(t.least > 1.0 && t.most < 60.0, "{t:?}");
        assert!(f.mean_error_mm().most < 20.0, "{:?}", f.mean_error_mm());
    }

    #[test]
    fn a_virtual_obstacle_on_the_path_is_foreseen() {
        let (arena, robot, mut definition) = planned();
        let clear = of(&arena, &robot, &definition, &[1]);
        // A box across the path's middle.
        let middle = definition.path[definition.path.len() / 2];
        definition.virtual_obstacles = vec![Shape::Rect {
            x_mm: middle.x_mm - 30.0,
            y_mm: middle.y_mm - 30.0,
            width_mm: 60.0,
            height_mm: 60.0,
        }];
        let blocked = of(&arena, &robot, &definition, &[1]);
        assert_eq!(
            blocked.reached(),
            0,
            "the safety layer holds the robot back"
        );
        assert!(blocked.held_back_s().most > clear.held_back_s().most);
        let (closest, at) = blocked.closest();
        assert!(closest < 10.0, "{closest}");
        assert!(at.distance(middle) < 80.0, "{at:?} by {middle:?}");
    }

    #[test]
    fn a_speed_cap_slows_the_forecast_and_nothing_is_forecast_without_a_path() {
        let (arena, robot, mut definition) = planned();
        let free = of(&arena, &robot, &definition, &[1]);
        definition.max_speed_mm_s = Some(40.0);
        let capped = of(&arena, &robot, &definition, &[1]);
        assert!(capped.saturated_s().most > 0.0);
        assert!(capped.runs[0].seconds > free.runs[0].seconds);
        definition.path.clear();
        let none = forecast(Forecasting {
            arena: &arena,
            robot: &robot,
            start: arena.start,
            definition: &definition,
            seeds: &[1],
        });
        assert_eq!(none, Err(ForecastError::NoPath));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(8))]

        /// The same seed foresees the same run; every figure is within what
        /// a run can be.
        #[test]
        fn forecasts_are_repeatable_and_within_bounds(seed in any::<u64>()) {
            let (arena, robot, definition) = planned();
            let a = of(&arena, &robot, &definition, &[seed]);
            let b = of(&arena, &robot, &definition, &[seed]);
            prop_assert_eq!(&a, &b);
            let r = &a.runs[0];
            prop_assert!(r.seconds <= LONGEST_S + STEP_S);
            prop_assert!(r.held_back_s <= r.seconds + 1e-9);
            prop_assert!(r.saturated_s <= r.seconds + 1e-9);
            prop_assert!(r.closest_mm.is_finite());
            prop_assert!(r.collisions == 0 || r.closest_mm <= 0.5);
        }
    }
}
