//! The Guest's pilot: plans the path it defines for a goal, and during a
//! run turns each feedback into the next drive along that path. The window
//! and the headless client both fly through it, so planning margins, goal
//! tolerance and the follower's gains have one home.

use vl_core::{ArenaPlanError, Definition, Drive, Follower, Goal, Plan, Pose, Shape, plan_route};

use crate::session::RobotState;
use vl_core::MountedLab;

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

/// Steers along the defined path during a run.
#[derive(Debug, Clone, Default)]
pub struct Pilot {
    follower: Option<Follower>,
}

impl Pilot {
    /// Takes over the definition's path for a run; without a path there
    /// is nothing to follow and the operator drives.
    pub fn follow(&mut self, definition: &Definition) {
        self.follower = Follower::for_definition(definition);
    }

    /// Stops following (the run ended).
    pub fn release(&mut self) {
        self.follower = None;
    }

    pub fn is_following(&self) -> bool {
        self.follower.is_some()
    }

    /// The drive along the path for the robot's latest state; `None` when
    /// not following.
    pub fn steer(&mut self, lab: &MountedLab, robot: &RobotState) -> Option<Drive> {
        let follower = self.follower.as_mut()?;
        let wheels = follower
            .step(&lab.robot, robot.pose, &robot.proximity)
            .wheels();
        Some(Drive::from(wheels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Arena, CameraModel, Experiment, Point, RobotModel, WheelSpeeds};

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
    fn routes_define_the_goal_and_the_path_the_pilot_follows() {
        let lab = lab();
        let goal = Goal::at(lab.arena.goal.unwrap());
        let route = Route::plan(&lab, lab.arena.start, goal, Vec::new()).unwrap();
        assert_eq!(route.definition.goal, Some(goal));
        assert_eq!(route.definition.path.last(), Some(&goal.point()));
        assert!(route.body_clearance_mm(&lab) > 0.0);
        let mut pilot = Pilot::default();
        let robot = RobotState {
            event: 0,
            t_ms: 0.0,
            pose: lab.arena.start,
            wheels: WheelSpeeds::default(),
            proximity: vec![0; 8],
            contact: false,
            force: None,
            limited: false,
        };
        assert_eq!(pilot.steer(&lab, &robot), None, "nothing to follow yet");
        pilot.follow(&route.definition);
        assert!(matches!(
            pilot.steer(&lab, &robot),
            Some(Drive::Wheels { .. })
        ));
        let there = RobotState {
            pose: Pose {
                x_mm: goal.x_mm,
                y_mm: goal.y_mm,
                theta_rad: 0.0,
            },
            ..robot
        };
        assert_eq!(
            pilot.steer(&lab, &there),
            Some(Drive::Wheels {
                left: 0.0,
                right: 0.0
            }),
            "arrived: stop"
        );
        let blocked = Goal::at(Point {
            x_mm: 280.0,
            y_mm: 100.0,
        });
        assert!(Route::plan(&lab, lab.arena.start, blocked, Vec::new()).is_err());
    }
}
