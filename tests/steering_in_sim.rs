//! The go-to-goal steering the headless Guest uses brings the simulated
//! robot to the navigation arena's goal, around the obstacles in its way.

use vl_core::arena::Arena;
use vl_core::robot::RobotModel;
use vl_core::steer::{Steering, go_to_goal};
use vl_sim::World;

#[test]
fn steering_reaches_the_navigation_goal() {
    for seed in 0..5 {
        let arena = Arena::navigation();
        let goal = arena.goal.expect("the navigation arena suggests a goal");
        let robot = RobotModel::khepera_ii();
        let mut world = World::new(arena, robot.clone(), seed).unwrap();
        let mut reached = false;
        // 60 simulated seconds, steering every 20 ms as the feedback loop does.
        for _ in 0..3000 {
            let proximity = world.proximity();
            let wheels = go_to_goal(&robot, world.pose(), goal, &proximity, Steering::default());
            world.set_wheels(wheels);
            world.run_for(0.02);
            if world.pose().point().distance(goal) < 15.0 {
                reached = true;
                break;
            }
        }
        assert!(
            reached,
            "seed {seed}: stuck at {:?} after {:.0} s",
            world.pose(),
            world.time_s()
        );
    }
}
