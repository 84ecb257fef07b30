//! The Guest's route: plans the path it defines for a goal on the mounted
//! lab's map (the floor as the Host's camera saw it). The window and the
//! headless client both plan through it; the Host follows the path.

use vl_core::{ArenaPlanError, Definition, Goal, MountedLab, Plan, Pose, Shape, plan_route};

/// A definition that reaches a goal, with the plan behind its path.
#[derive(Debug, Clone)]
pub struct Route {
    pub definition: Definition,
    pub plan: Plan,
}

impl Route {
    /// Plans from `start` to `goal` on the mounted lab's map around the
    /// virtual obstacles, and defines the goal with the planned path.
    pub fn plan(
        lab: &MountedLab,
        start: Pose,
        goal: Goal,
        virtual_obstacles: Vec<Shape>,
    ) -> Result<Route, ArenaPlanError> {
        let plan = plan_route(
            &lab.arena,
            &virtual_obstacles,
            &lab.robot,
            start,
            goal.point(),
        )?;
        let definition = Definition {
            goal: Some(goal),
            path: plan.points(),
            virtual_obstacles,
            ..Definition::default()
        };
        Ok(Route { definition, plan })
    }

    /// How close the robot's body comes to a mapped obstacle along the path, mm.
    pub fn body_clearance_mm(&self, lab: &MountedLab) -> f64 {
        self.definition
            .path
            .iter()
            .map(|&p| lab.arena.clearance(p) - lab.robot.radius_mm)
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Arena, CameraModel, Experiment, Point, RobotModel};

    fn lab() -> MountedLab {
        let arena = Arena::navigation();
        MountedLab {
            experiment: Experiment::Navigation,
            camera: CameraModel::overhead(arena.width_mm, arena.height_mm, 320, 15.0),
            robot: RobotModel::khepera_ii(),
            arena,
        }
    }

    #[test]
    fn routes_define_the_goal_and_a_clear_path_to_it() {
        let lab = lab();
        let goal = Goal::at(lab.arena.goal.unwrap());
        let route = Route::plan(&lab, lab.arena.start, goal, Vec::new()).unwrap();
        assert_eq!(route.definition.goal, Some(goal));
        assert_eq!(route.definition.path.last(), Some(&goal.point()));
        assert!(route.body_clearance_mm(&lab) > 0.0);
        let blocked = Goal::at(Point {
            x_mm: 280.0,
            y_mm: 100.0,
        });
        assert!(Route::plan(&lab, lab.arena.start, blocked, Vec::new()).is_err());
    }
}
