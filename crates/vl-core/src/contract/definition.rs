//! What a user defines before a run (the thesis's "define" functionality),
//! with the checks a definition must pass before the real robot moves, and
//! where a run of it ends.

use serde::{Deserialize, Serialize};

use crate::{Arena, Point, RobotModel, Shape, ShapeError, WheelSpeeds};

/// Where the robot should go, and how close counts as there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Goal {
    pub x_mm: f64,
    pub y_mm: f64,
    pub tolerance_mm: f64,
}

impl Goal {
    /// How close to a goal counts as there, unless the user says otherwise.
    pub const DEFAULT_TOLERANCE_MM: f64 = 15.0;

    /// A goal at `p` with the default tolerance.
    pub fn at(p: Point) -> Goal {
        Goal {
            x_mm: p.x_mm,
            y_mm: p.y_mm,
            tolerance_mm: Goal::DEFAULT_TOLERANCE_MM,
        }
    }

    pub fn point(&self) -> Point {
        Point {
            x_mm: self.x_mm,
            y_mm: self.y_mm,
        }
    }
}

/// The user's settings for one experiment run (the thesis's "define").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
pub struct Definition {
    /// The run ends with success when the robot is within tolerance of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<Goal>,
    /// A planned path, arena mm, for path-following experiments.
    #[serde(default)]
    pub path: Vec<Point>,
    /// Points to visit in order, for experiments that define them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub waypoints: Vec<Point>,
    /// Obstacles that exist only in software; the Host keeps the robot out of them.
    #[serde(default)]
    pub virtual_obstacles: Vec<Shape>,
    /// Cap on wheel speed for this run, below the robot's own limit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_speed_mm_s: Option<f64>,
    /// The run is stopped when it lasts longer than this.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_limit_s: Option<f64>,
    /// How far ahead on the path the Host's follower aims, mm (thesis F.6:
    /// shorter tracks tighter, longer cuts corners smoother).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lookahead_mm: Option<f64>,
    /// The user's own controller the run drives with, by its hash: the
    /// module sent before (`controller` messages).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<crate::ModuleHash>,
}

/// How many of a definition's waypoints a run has visited, in order.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema,
)]
pub struct Visited(pub usize);

impl Visited {
    /// After the robot stood at `p`: the next waypoint counts when `p` is
    /// within `definition`'s tolerance of it.
    #[must_use]
    pub fn at(self, definition: &Definition, p: Point) -> Visited {
        match definition.waypoints.get(self.0) {
            Some(next) if p.distance(*next) <= definition.tolerance_mm() => Visited(self.0 + 1),
            _ => self,
        }
    }
}

/// The look-ahead a definition may ask for, mm: from a fraction of the
/// robot to a few bodies ahead.
pub const LOOKAHEAD_MM: std::ops::RangeInclusive<f64> = 5.0..=200.0;

/// The most path points a definition may carry: a path across the largest
/// arena at a quarter-cell spacing has a few thousand.
pub(crate) const MAX_PATH_POINTS: usize = 10_000;
/// The most waypoints a definition may carry, and an experiment ask for.
pub(crate) const MAX_WAYPOINTS: usize = 64;
/// The most virtual obstacles a definition may carry.
pub(crate) const MAX_VIRTUAL_OBSTACLES: usize = 64;
/// The most vertices one virtual polygon may have, and all of a
/// definition's virtual obstacles together (a box or circle counts 4): the
/// safety layer measures the distance to them every control period, so
/// their size bounds its time.
pub(crate) const MAX_POLYGON_VERTICES: usize = 256;
pub(crate) const MAX_VIRTUAL_VERTICES: usize = 1024;

/// What is wrong with a definition, in words a user can act on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DefinitionError {
    #[error("{what} must be a positive number, got {value}")]
    NotPositive { what: &'static str, value: f64 },
    #[error("the path has {0} points, more than the {MAX_PATH_POINTS} a definition may carry")]
    TooManyPoints(usize),
    #[error(
        "there are {0} virtual obstacles, more than the {MAX_VIRTUAL_OBSTACLES} a definition may carry"
    )]
    TooManyObstacles(usize),
    #[error(
        "the virtual obstacles have {0} vertices in all, more than the {MAX_VIRTUAL_VERTICES} a definition may carry"
    )]
    TooManyVertices(usize),
    #[error(
        "virtual obstacle {index} has {vertices} vertices, more than the {MAX_POLYGON_VERTICES} a polygon may have"
    )]
    PolygonTooBig { index: usize, vertices: usize },
    #[error("virtual obstacle {index}: {why}")]
    BadObstacle { index: usize, why: ShapeError },
    #[error(
        "virtual obstacle {index} reaches ({:.0}, {:.0})–({:.0}, {:.0}) mm, far off the {:.0} × {:.0} mm arena",
        lo.x_mm, lo.y_mm, hi.x_mm, hi.y_mm, arena_mm.0, arena_mm.1
    )]
    FarOff {
        index: usize,
        lo: Point,
        hi: Point,
        arena_mm: (f64, f64),
    },
    #[error(
        "the goal ({:.0}, {:.0}) mm is outside the {:.0} × {:.0} mm arena",
        goal.x_mm, goal.y_mm, arena_mm.0, arena_mm.1
    )]
    GoalOutside { goal: Point, arena_mm: (f64, f64) },
    #[error(
        "the robot cannot stand at the goal ({:.0}, {:.0}) mm: it overlaps an obstacle or wall",
        .0.x_mm, .0.y_mm
    )]
    GoalBlocked(Point),
    #[error("path point {0} is not a finite position")]
    PathNotFinite(usize),
    #[error("there are {0} waypoints, more than the {MAX_WAYPOINTS} a definition may carry")]
    TooManyWaypoints(usize),
    #[error(
        "waypoint {} ({:.0}, {:.0}) mm is outside the {:.0} × {:.0} mm arena",
        index + 1, point.x_mm, point.y_mm, arena_mm.0, arena_mm.1
    )]
    WaypointOutside {
        index: usize,
        point: Point,
        arena_mm: (f64, f64),
    },
    #[error(
        "the robot cannot stand at waypoint {} ({:.0}, {:.0}) mm: it overlaps an obstacle or wall",
        index + 1, point.x_mm, point.y_mm
    )]
    WaypointBlocked { index: usize, point: Point },
    #[error(
        "the path does not pass waypoint {} ({:.0}, {:.0}) mm after the ones before it: plan it again through every point",
        index + 1, point.x_mm, point.y_mm
    )]
    WaypointMissed { index: usize, point: Point },
    #[error(
        "the look-ahead must be from {lo} to {hi} mm, not {0}",
        lo = LOOKAHEAD_MM.start(),
        hi = LOOKAHEAD_MM.end()
    )]
    Lookahead(f64),
}

impl Definition {
    /// `wheels` within the robot's limits and this definition's speed cap:
    /// what a run of it may ask of the wheels, live or forecast.
    pub fn capped(&self, robot: &RobotModel, wheels: WheelSpeeds) -> WheelSpeeds {
        match self.max_speed_mm_s {
            Some(limit) => {
                let mut capped = robot.clone();
                capped.max_wheel_speed_mm_s = capped.max_wheel_speed_mm_s.min(limit);
                capped.clamp(wheels)
            }
            None => robot.clamp(wheels),
        }
    }

    /// The fastest a wheel may turn in a run of it, mm/s: the robot's
    /// limit, or the definition's cap if lower.
    pub fn speed_limit_mm_s(&self, robot: &RobotModel) -> f64 {
        self.max_speed_mm_s
            .map_or(robot.max_wheel_speed_mm_s, |cap| {
                cap.min(robot.max_wheel_speed_mm_s)
            })
    }

    /// Whether `p` is within the goal's tolerance.
    pub fn at_goal(&self, p: Point) -> bool {
        self.goal
            .is_some_and(|g| p.distance(g.point()) <= g.tolerance_mm)
    }

    /// How close to a waypoint counts as there: the goal's tolerance.
    pub fn tolerance_mm(&self) -> f64 {
        self.goal
            .map_or(Goal::DEFAULT_TOLERANCE_MM, |g| g.tolerance_mm)
    }

    /// Whether a run standing at `p`, having `visited` its waypoints so
    /// far, has reached where it ends: every waypoint in order when it has
    /// some, else the goal. Where a run whose experiment ends there ends,
    /// live or forecast.
    pub fn reached(&self, visited: Visited, p: Point) -> bool {
        match self.waypoints.is_empty() {
            true => self.at_goal(p),
            false => visited.0 >= self.waypoints.len(),
        }
    }

    /// Whether the Host follows this definition's path by itself in a run
    /// that `follows` (its experiment's, [`Experiment::follows`]): when it
    /// has a path. The operator's commands then only take over while they
    /// keep coming.
    pub fn host_follows(&self, follows: bool) -> bool {
        follows && !self.path.is_empty()
    }

    /// The points it carries: its path's and its virtual obstacles'
    /// vertices, what checking, sending and trying it costs.
    pub fn size(&self) -> usize {
        self.path.len()
            + self.waypoints.len()
            + self
                .virtual_obstacles
                .iter()
                .map(Shape::vertices)
                .sum::<usize>()
    }

    /// Checks the definition against the arena and robot it will run on,
    /// saying what is wrong in words a user can act on.
    pub fn validate(&self, arena: &Arena, robot: &RobotModel) -> Result<(), DefinitionError> {
        use DefinitionError as E;
        let positive = |what: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(E::NotPositive { what, value })
            }
        };
        if self.path.len() > MAX_PATH_POINTS {
            return Err(E::TooManyPoints(self.path.len()));
        }
        if self.virtual_obstacles.len() > MAX_VIRTUAL_OBSTACLES {
            return Err(E::TooManyObstacles(self.virtual_obstacles.len()));
        }
        let vertices = self.size() - self.path.len() - self.waypoints.len();
        if vertices > MAX_VIRTUAL_VERTICES {
            return Err(E::TooManyVertices(vertices));
        }
        let arena_mm = (arena.width_mm, arena.height_mm);
        for (index, o) in self.virtual_obstacles.iter().enumerate() {
            if o.vertices() > MAX_POLYGON_VERTICES {
                return Err(E::PolygonTooBig {
                    index,
                    vertices: o.vertices(),
                });
            }
            o.check().map_err(|why| E::BadObstacle { index, why })?;
            // On the floor, give or take the arena's own size: numbers far
            // beyond it are a mistake, and would only cost time.
            let (lo, hi) = o.bounds();
            let (w, h) = arena_mm;
            if lo.x_mm < -w || lo.y_mm < -h || hi.x_mm > 2.0 * w || hi.y_mm > 2.0 * h {
                return Err(E::FarOff {
                    index,
                    lo,
                    hi,
                    arena_mm,
                });
            }
        }
        if let Some(goal) = self.goal {
            positive("the goal tolerance", goal.tolerance_mm)?;
            let p = goal.point();
            let inside = (0.0..=arena.width_mm).contains(&p.x_mm)
                && (0.0..=arena.height_mm).contains(&p.y_mm);
            if !inside {
                return Err(E::GoalOutside { goal: p, arena_mm });
            }
            if !self.is_free(arena, p, robot.radius_mm) {
                return Err(E::GoalBlocked(p));
            }
        }
        if let Some(i) = self
            .path
            .iter()
            .position(|p| !(p.x_mm.is_finite() && p.y_mm.is_finite()))
        {
            return Err(E::PathNotFinite(i));
        }
        if self.waypoints.len() > MAX_WAYPOINTS {
            return Err(E::TooManyWaypoints(self.waypoints.len()));
        }
        for (index, &point) in self.waypoints.iter().enumerate() {
            let inside = (0.0..=arena.width_mm).contains(&point.x_mm)
                && (0.0..=arena.height_mm).contains(&point.y_mm);
            if !inside {
                return Err(E::WaypointOutside {
                    index,
                    point,
                    arena_mm,
                });
            }
            if !self.is_free(arena, point, robot.radius_mm) {
                return Err(E::WaypointBlocked { index, point });
            }
        }
        // A path followed to its end must visit every waypoint on the way.
        if !self.path.is_empty() {
            let visited = (self.path.iter()).fold(Visited::default(), |v, &p| v.at(self, p));
            if let Some(&point) = self.waypoints.get(visited.0) {
                return Err(E::WaypointMissed {
                    index: visited.0,
                    point,
                });
            }
        }
        if let Some(v) = self.max_speed_mm_s {
            positive("the speed limit", v)?;
        }
        if let Some(l) = self.lookahead_mm
            && !LOOKAHEAD_MM.contains(&l)
        {
            return Err(E::Lookahead(l));
        }
        if let Some(t) = self.time_limit_s {
            positive("the time limit", t)?;
        }
        Ok(())
    }

    /// Whether a disc of `radius_mm` at `p` clears the arena and this
    /// definition's virtual obstacles.
    pub fn is_free(&self, arena: &Arena, p: Point, radius_mm: f64) -> bool {
        arena.is_free(p, radius_mm)
            && self
                .virtual_obstacles
                .iter()
                .all(|o| o.distance(p) > radius_mm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn goal(x_mm: f64, y_mm: f64) -> Definition {
        Definition {
            goal: Some(Goal {
                x_mm,
                y_mm,
                tolerance_mm: 20.0,
            }),
            ..Definition::default()
        }
    }

    #[test]
    fn goals_must_be_reachable_places() {
        let arena = Arena::navigation();
        let robot = RobotModel::khepera_ii();
        assert_eq!(goal(680.0, 470.0).validate(&arena, &robot), Ok(()));
        let outside = goal(900.0, 100.0).validate(&arena, &robot).unwrap_err();
        assert!(outside.to_string().contains("outside"), "{outside}");
        let blocked = goal(280.0, 100.0).validate(&arena, &robot).unwrap_err();
        assert!(blocked.to_string().contains("overlaps"), "{blocked}");
        let mut virtual_block = goal(680.0, 470.0);
        virtual_block.virtual_obstacles.push(Shape::Circle {
            x_mm: 680.0,
            y_mm: 470.0,
            radius_mm: 10.0,
        });
        assert!(virtual_block.validate(&arena, &robot).is_err());
        let mut slow = goal(680.0, 470.0);
        slow.max_speed_mm_s = Some(-1.0);
        assert!(
            slow.validate(&arena, &robot)
                .unwrap_err()
                .to_string()
                .contains("speed limit")
        );
    }
}
