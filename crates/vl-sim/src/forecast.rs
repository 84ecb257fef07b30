//! A navigation definition tried on the lab's twin before the robot moves
//! (issue 29): the same follower and the same safety layer as the Host's
//! run, on the simulated robot of the same model in the lab's arena with
//! the definition's virtual obstacles, over a few seeds of sensor and
//! wheel noise, far faster than real time. What it foresees — whether and
//! when the goal is reached, the closest approach and where, contacts, how
//! long the safety layer holds the robot back and the wheels saturate, how
//! well the path is kept — is what a lab can refuse a definition for
//! before anything moves, and what a run is later compared with.

use std::sync::atomic::{AtomicBool, Ordering};

use thiserror::Error;
use vl_core::{
    Arena, Closest, Controller, ControllerFault, Definition, Follower, Forecast, Leash,
    Observation, Point, Pose, RobotModel, STEP_PERIOD_S, Safety, SeedRun, Situation, Steer,
    Surroundings, Told, Visited, WheelSpeeds,
};

use crate::world::{STEP_S, SimError, World};

/// How often the proximity sensors are read, in steps: the Khepera's IR
/// period, as the Host reads them.
const SENSE_EVERY_STEPS: u64 = 2;
/// A foreseen path keeps a point this often, in steps: 10 a second…
const PATH_EVERY_STEPS: u64 = 10;
/// …and at most this many points (a long run keeps fewer a second), so a
/// forecast always fits in one message.
const MOST_PATH_POINTS: usize = 300;
/// How often a forecast looks whether it is still wanted, in steps.
const CANCEL_EVERY_STEPS: u64 = 100;
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
    /// Set when the forecast is no longer wanted (a newer definition).
    pub cancel: Option<&'a AtomicBool>,
    /// Who drives.
    pub pilot: Pilot<'a>,
}

/// A fresh user's controller for each seed's run.
pub type Controllers<'a> = &'a (dyn Fn() -> Result<Box<dyn Controller>, ControllerFault> + Sync);

/// Who drives a forecast run.
#[derive(Clone, Copy)]
pub enum Pilot<'a> {
    /// The lab's follower, along the definition's path.
    Path,
    /// A user's controller, stepped every `STEP_PERIOD_S` as the Host steps
    /// it, until it says it is done or reaches the goal.
    Controller(Controllers<'a>),
}

impl std::fmt::Debug for Pilot<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Pilot::Path => "Path",
            Pilot::Controller(_) => "Controller",
        })
    }
}

/// A user's controller's runs last at most this long unless the
/// definition says less, s.
pub const CONTROLLER_S: f64 = 60.0;
/// The controller's steps, in simulator steps.
const CONTROLLER_EVERY_STEPS: u64 = (STEP_PERIOD_S / STEP_S + 0.5) as u64;

/// What a driver does next.
enum Next {
    Drive(WheelSpeeds),
    /// The follower is at the goal.
    Arrived,
    /// The controller says it is done.
    Finished,
    Stopped(ControllerFault),
}

impl Next {
    /// How a run that ended so counts: the goal reached (a controller
    /// done where no goal was asked), or the controller stopped, why.
    fn end(self, out: &mut SeedRun, definition: &Definition) {
        match self {
            Next::Drive(_) => {}
            Next::Arrived => out.reached_goal = true,
            Next::Finished => out.reached_goal = definition.goal.is_none(),
            Next::Stopped(fault) => out.fault = Some(fault.to_string()),
        }
    }
}

/// What drives one seed's run, as it goes.
enum Driver {
    Path(Follower),
    Controller {
        controller: Box<dyn Controller>,
        /// Its last answer, held until the next step.
        wheels: WheelSpeeds,
    },
}

#[derive(Debug, Error, PartialEq)]
pub enum ForecastError {
    #[error("the definition has no path to follow: only a navigation run with a path is forecast")]
    NoPath,
    #[error("no seeds to forecast with")]
    NoSeeds,
    #[error("the forecast was cancelled")]
    Cancelled,
    #[error("{0}")]
    Controller(#[from] ControllerFault),
    #[error("{0}")]
    World(#[from] SimError),
}

impl Driver {
    fn new(pilot: Pilot<'_>, definition: &Definition) -> Result<Driver, ForecastError> {
        Ok(match pilot {
            Pilot::Path => {
                Driver::Path(Follower::for_definition(definition).ok_or(ForecastError::NoPath)?)
            }
            Pilot::Controller(controllers) => Driver::Controller {
                controller: controllers()?,
                wheels: WheelSpeeds::default(),
            },
        })
    }

    /// How long a run of `definition` may last, s: its own limit, or for
    /// a path twice as long as following it should take.
    fn limit_s(&self, definition: &Definition) -> f64 {
        let unless = match self {
            Driver::Path(follower) => {
                2.0 * follower.expected_seconds(definition.max_speed_mm_s) + 5.0
            }
            Driver::Controller { .. } => CONTROLLER_S,
        };
        definition.time_limit_s.unwrap_or(unless).min(LONGEST_S)
    }

    /// How far `p` is from the path followed, mm (a controller has none).
    fn off_path_mm(&self, p: Point) -> f64 {
        match self {
            Driver::Path(follower) => follower.distance_to_path(p),
            Driver::Controller { .. } => 0.0,
        }
    }

    /// What to ask of the wheels at `steps` into the run.
    fn next(
        &mut self,
        robot: &RobotModel,
        definition: &Definition,
        world: &World,
        proximity: &[u16],
        steps: u64,
    ) -> Next {
        let pose = world.pose();
        match self {
            Driver::Path(follower) => match follower.step(robot, pose, proximity) {
                Steer::Drive(asked) => Next::Drive(asked),
                Steer::Arrived => Next::Arrived,
            },
            // Between its steps, its last answer holds, as on the Host.
            Driver::Controller { wheels, .. } if !steps.is_multiple_of(CONTROLLER_EVERY_STEPS) => {
                Next::Drive(*wheels)
            }
            Driver::Controller { controller, wheels } => {
                let seen = Observation {
                    t_s: world.time_s(),
                    pose,
                    uncertainty_mm: 0.0,
                    wheels: world.wheels(),
                    goal: definition.goal.map(|g| g.point()),
                    proximity: Observation::proximity_of(proximity),
                    period_s: STEP_PERIOD_S,
                    speed_limit_mm_s: definition.speed_limit_mm_s(robot),
                };
                match controller.step(&seen) {
                    Ok(answer) if answer.finished => Next::Finished,
                    Ok(answer) => {
                        *wheels = answer.wheels;
                        Next::Drive(answer.wheels)
                    }
                    Err(fault) => Next::Stopped(fault),
                }
            }
        }
    }
}

/// Forecasts `what`: one run per seed.
pub fn forecast(what: Forecasting<'_>) -> Result<Forecast, ForecastError> {
    if what.seeds.is_empty() {
        return Err(ForecastError::NoSeeds);
    }
    let mut runs: Vec<SeedRun> = what
        .seeds
        .iter()
        .map(|&seed| run(&what, seed))
        .collect::<Result<_, _>>()?;
    // Every seed's path thinned alike, so that point i is at the same time.
    let longest = runs.iter().map(|r| r.path.len()).max().unwrap_or(0);
    let stride = longest.div_ceil(MOST_PATH_POINTS).max(1);
    for r in &mut runs {
        let last = r.path.last().copied();
        r.path = r.path.iter().copied().step_by(stride).collect();
        if r.path.last().copied() != last {
            r.path.extend(last);
        }
    }
    Ok(Forecast {
        runs,
        path_every_s: stride as f64 * PATH_EVERY_STEPS as f64 * STEP_S,
    })
}

/// One forecast run, as the Host's control loop would drive it.
fn run(what: &Forecasting<'_>, seed: u64) -> Result<SeedRun, ForecastError> {
    let Forecasting {
        robot, definition, ..
    } = *what;
    let mut driver = Driver::new(what.pilot, definition)?;
    let arena = Arena {
        start: what.start,
        ..what.arena.clone()
    };
    let surroundings = Surroundings::new(&arena).with(&definition.virtual_obstacles);
    let mut world = World::new(arena, robot.clone(), seed)?;
    let limit_s = driver.limit_s(definition);
    let safety = Safety::default();
    let room = |p: Point| surroundings.clearance(p) - robot.radius_mm;
    let closest = |p: Point| Closest {
        mm: room(p),
        at: p,
        to: surroundings.nearest(p),
    };
    // The last leash, and the wheels' travel its reach counts from.
    let mut told: Option<(Leash, [f64; 2])> = None;
    let mut proximity = world.proximity();
    let start = what.start.point();
    let mut out = SeedRun {
        seed,
        reached_goal: false,
        seconds: 0.0,
        closest: closest(start),
        end: closest(start),
        collisions: 0,
        first_contact: None,
        held_back_s: 0.0,
        saturated_s: 0.0,
        mean_error_mm: 0.0,
        path: vec![start],
        fault: None,
    };
    let (mut error_sum, mut steps) = (0.0, 0u64);
    let mut visited = Visited::default();
    while world.time_s() < limit_s {
        if steps % CANCEL_EVERY_STEPS == 0 && what.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
        {
            return Err(ForecastError::Cancelled);
        }
        if steps % SENSE_EVERY_STEPS == 0 {
            proximity = world.proximity();
        }
        let pose = world.pose();
        // The run ends where the Host ends it: within the goal's tolerance,
        // or with every waypoint visited in order.
        visited = visited.at(definition, pose.point());
        if definition.reached(visited, pose.point()) {
            out.reached_goal = true;
            break;
        }
        let asked = match driver.next(robot, definition, &world, &proximity, steps) {
            Next::Drive(asked) => asked,
            ended => {
                ended.end(&mut out, definition);
                break;
            }
        };
        let wanted = definition.capped(robot, asked);
        if wanted != asked {
            out.saturated_s += STEP_S;
        }
        let travel = world.wheel_travel_mm();
        let situation = Situation {
            pose,
            wheels: world.wheels(),
            told: Told::seen_from(told, travel),
            proximity: &proximity,
        };
        let guarded = safety.guard(robot, &surroundings, situation, wanted);
        if guarded.limited {
            out.held_back_s += STEP_S;
        }
        told = Some((guarded.leash, travel));
        world.drive(&guarded.leash, travel);
        world.step();
        steps += 1;
        let here = world.pose().point();
        let room = room(here);
        if room < out.closest.mm {
            out.closest.mm = room;
            out.closest.at = here;
        }
        if out.first_contact.is_none() && world.collisions() > 0 {
            out.first_contact = Some(here);
        }
        error_sum += driver.off_path_mm(here);
        if steps % PATH_EVERY_STEPS == 0 {
            out.path.push(here);
        }
    }
    out.closest.to = surroundings.nearest(out.closest.at);
    let end = world.pose().point();
    out.end = closest(end);
    out.path.push(end);
    out.seconds = world.time_s();
    out.collisions = world.collisions();
    out.mean_error_mm = error_sum / steps.max(1) as f64;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use vl_core::{ForecastLimits, ForecastVerdict, Goal, Shape, plan_route};
    use vl_report::table::Report;

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
            cancel: None,
            pilot: Pilot::Path,
        })
        .unwrap()
    }

    #[test]
    fn a_planned_path_is_foreseen_to_reach_its_goal_clear_of_everything() {
        let (arena, robot, definition) = planned();
        let f = of(&arena, &robot, &definition, &[1, 2, 3]);
        println!(
            "{}",
            ForecastVerdict::new(f.clone(), ForecastLimits::default()).table()
        );
        assert_eq!(f.reached(), 3, "{f:?}");
        assert_eq!(f.collisions(), 0);
        let closest = f.closest().unwrap().mm;
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
        let closest = blocked.closest().unwrap();
        assert!(closest.mm < 10.0, "{closest:?}");
        assert!(
            closest.at.distance(middle) < 80.0,
            "{closest:?} by {middle:?}"
        );
        assert_eq!(closest.to, vl_core::Nearest::VirtualObstacle(0));
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
            cancel: None,
            pilot: Pilot::Path,
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
            prop_assert!(r.closest.mm.is_finite());
            prop_assert!(r.collisions == 0 || r.closest.mm <= 0.5);
            prop_assert!(r.path.len() <= MOST_PATH_POINTS + 1);
        }
    }
}
