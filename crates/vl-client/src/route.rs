//! The Guest's route: plans the path it defines for a goal on the mounted
//! lab's map (the floor as the Host's camera saw it). The window and the
//! headless client both plan through it; the Host follows the path.

use thiserror::Error;
use vl_core::{
    ArenaPlanError, CSpaceError, Definition, Goal, MountedLab, Plan, Point, Pose, Shape,
    disc_cspace, plan_route_through,
};

use crate::settings::Settings;

/// How far along the path, each way, dragging one point bends it, mm.
const EDIT_REACH_MM: f64 = 60.0;

/// Why an edited path was not accepted (thesis F.4).
#[derive(Debug, Error, PartialEq)]
pub enum EditRefused {
    #[error(
        "the changed path enters the C-space at ({x_mm:.0}, {y_mm:.0}) mm: the robot's body would touch an obstacle there"
    )]
    Blocked { x_mm: f64, y_mm: f64 },
    #[error("the path's ends stay where they are: the start is the robot, the end the goal")]
    End,
    #[error(transparent)]
    Map(#[from] CSpaceError),
}

/// `path` with sample `index` moved to `to`, and the samples around it
/// moved with it, less the further along the path they are (a cosine bump
/// over [`EDIT_REACH_MM`] each way), so the path stays smooth. Its ends
/// stay: the start is where the robot is, the end the goal.
pub fn drag_path(path: &[Point], index: usize, to: Point) -> Result<Vec<Point>, EditRefused> {
    if index == 0 || index + 1 >= path.len() {
        return Err(EditRefused::End);
    }
    let (dx, dy) = (to.x_mm - path[index].x_mm, to.y_mm - path[index].y_mm);
    let mut arc = vec![0.0; path.len()];
    for k in 1..path.len() {
        arc[k] = arc[k - 1] + path[k].distance(path[k - 1]);
    }
    let last = path.len() - 1;
    Ok(path
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let s = (arc[k] - arc[index]).abs();
            let w = if k == 0 || k == last || s >= EDIT_REACH_MM {
                0.0
            } else {
                0.5 * (1.0 + (std::f64::consts::PI * s / EDIT_REACH_MM).cos())
            };
            Point {
                x_mm: p.x_mm + w * dx,
                y_mm: p.y_mm + w * dy,
            }
        })
        .collect())
}

/// Whether the robot's centre may go along all of `path`: every sample
/// outside the C-space of the lab's map and `virtual_obstacles`.
pub fn check_path(
    lab: &MountedLab,
    virtual_obstacles: &[Shape],
    path: &[Point],
) -> Result<(), EditRefused> {
    let cspace = disc_cspace(
        &lab.scene.arena,
        virtual_obstacles,
        lab.scene.robot.radius_mm,
    )?;
    match path.iter().find(|&&p| !cspace.is_free(p, 0.0)) {
        Some(p) => Err(EditRefused::Blocked {
            x_mm: p.x_mm,
            y_mm: p.y_mm,
        }),
        None => Ok(()),
    }
}

/// A definition that reaches a goal, with the plan behind its path.
#[derive(Debug, Clone)]
pub struct Route {
    pub definition: Definition,
    pub plan: Plan,
}

impl Route {
    /// Plans from `start` to `goal` on the mounted lab's map around the
    /// virtual obstacles, keeping the settings' margin, and defines the
    /// goal with the planned path and the settings' speed and look-ahead.
    pub fn plan(
        lab: &MountedLab,
        start: Pose,
        goal: Goal,
        virtual_obstacles: Vec<Shape>,
        settings: &Settings,
    ) -> Result<Route, ArenaPlanError> {
        Route::through(lab, start, goal, &[], virtual_obstacles, settings)
    }

    /// Plans from `start` through `waypoints` in order, as
    /// [`Route::plan`] does to one goal: the definition holds the
    /// waypoints, the last as its goal (`tolerance_mm` around each).
    pub fn plan_through(
        lab: &MountedLab,
        start: Pose,
        waypoints: &[Point],
        tolerance_mm: f64,
        virtual_obstacles: Vec<Shape>,
        settings: &Settings,
    ) -> Result<Route, ArenaPlanError> {
        let Some(&last) = waypoints.last() else {
            return Err(ArenaPlanError::NoPath(vl_core::NoPath::Disconnected));
        };
        let goal = Goal {
            tolerance_mm,
            ..Goal::at(last)
        };
        Route::through(lab, start, goal, waypoints, virtual_obstacles, settings)
    }

    /// The route from `start` through `waypoints` (none, or ending at the
    /// goal) to `goal`.
    fn through(
        lab: &MountedLab,
        start: Pose,
        goal: Goal,
        waypoints: &[Point],
        virtual_obstacles: Vec<Shape>,
        settings: &Settings,
    ) -> Result<Route, ArenaPlanError> {
        let points = match waypoints.is_empty() {
            true => vec![goal.point()],
            false => waypoints.to_vec(),
        };
        let plan = plan_route_through(
            &lab.scene.arena,
            &virtual_obstacles,
            &lab.scene.robot,
            start,
            &points,
            settings.margin_mm,
        )?;
        let definition = Definition {
            goal: Some(goal),
            waypoints: waypoints.to_vec(),
            path: plan.points(),
            virtual_obstacles,
            max_speed_mm_s: settings.max_speed_mm_s,
            lookahead_mm: Some(settings.lookahead_mm),
            ..Definition::default()
        };
        Ok(Route { definition, plan })
    }

    /// `n` points along the path, evenly by length, the last its end: where
    /// to visit on the way when none are given.
    pub fn along(&self, n: usize) -> Vec<Point> {
        let path = &self.definition.path;
        let mut at = vec![0.0];
        for pair in path.windows(2) {
            at.push(at[at.len() - 1] + pair[0].distance(pair[1]));
        }
        let length = at[at.len() - 1];
        (1..=n)
            .filter_map(|k| {
                let wanted = length * k as f64 / n as f64;
                let i = at.iter().position(|&s| s >= wanted - 1e-9)?;
                path.get(i).copied()
            })
            .collect()
    }

    /// How close the robot's body comes to a mapped obstacle along the path, mm.
    pub fn body_clearance_mm(&self, lab: &MountedLab) -> f64 {
        self.definition
            .path
            .iter()
            .map(|&p| lab.scene.arena.clearance(p) - lab.scene.robot.radius_mm)
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Arena, CameraModel, Point, RobotModel};

    fn lab() -> MountedLab {
        let arena = Arena::navigation();
        MountedLab {
            experiment: vl_core::ExperimentId::new("navigation").unwrap(),
            scene: vl_core::LabScene {
                camera: CameraModel::overhead(arena.width_mm, arena.height_mm, 320, 15.0),
                robot: RobotModel::khepera_ii(),
                arena,
            },
        }
    }

    #[test]
    fn a_dragged_path_bends_smoothly_and_is_checked_against_the_cspace() {
        let lab = lab();
        let goal = Goal::at(lab.scene.arena.goal.unwrap());
        let route = Route::plan(
            &lab,
            lab.scene.arena.start,
            goal,
            Vec::new(),
            &Settings::default(),
        )
        .unwrap();
        let path = route.definition.path.clone();
        let mid = path.len() / 2;
        let to = Point {
            x_mm: path[mid].x_mm + 10.0,
            y_mm: path[mid].y_mm - 10.0,
        };
        let bent = drag_path(&path, mid, to).unwrap();
        assert_eq!(bent[mid], to);
        assert_eq!(
            (bent[0], bent[bent.len() - 1]),
            (path[0], path[path.len() - 1])
        );
        // Neighbours follow less and less; far samples do not move.
        let moved = |k: usize| bent[k].distance(path[k]);
        assert!(moved(mid + 3) < moved(mid) && moved(mid + 3) > 0.0);
        assert_eq!(moved(mid + 200), 0.0);
        assert_eq!(check_path(&lab, &[], &bent), Ok(()));
        // Onto the circular obstacle at (420, 170): refused, naming where.
        let into = drag_path(
            &path,
            mid,
            Point {
                x_mm: 420.0,
                y_mm: 170.0,
            },
        )
        .unwrap();
        assert!(matches!(
            check_path(&lab, &[], &into),
            Err(EditRefused::Blocked { .. })
        ));
        assert_eq!(drag_path(&path, 0, to), Err(EditRefused::End));
    }

    #[test]
    fn routes_define_the_goal_and_a_clear_path_to_it() {
        let lab = lab();
        let goal = Goal::at(lab.scene.arena.goal.unwrap());
        let route = Route::plan(
            &lab,
            lab.scene.arena.start,
            goal,
            Vec::new(),
            &Settings::default(),
        )
        .unwrap();
        assert_eq!(route.definition.goal, Some(goal));
        assert_eq!(route.definition.path.last(), Some(&goal.point()));
        assert!(route.body_clearance_mm(&lab) > 0.0);
        let blocked = Goal::at(Point {
            x_mm: 280.0,
            y_mm: 100.0,
        });
        assert!(
            Route::plan(
                &lab,
                lab.scene.arena.start,
                blocked,
                Vec::new(),
                &Settings::default()
            )
            .is_err()
        );
    }
}
