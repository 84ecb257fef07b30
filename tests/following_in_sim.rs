//! Path following in the simulator: in every shipped arena, a path planned
//! on the arena's map brings the simulated Khepera to the goal without a
//! collision, and the robot keeps close to the path all the way.

use vl_core::{Arena, Goal, Point, RobotModel, plan_route};
use vl_sim::{Driver, World, run};

#[test]
fn planned_paths_are_followed_to_the_goal_in_every_shipped_arena() {
    println!(
        "{:<11} {:>4} {:>9} {:>8} {:>11} {:>10}",
        "arena", "seed", "path mm", "time s", "mean err mm", "max err mm"
    );
    for name in Arena::shipped() {
        let arena = Arena::named(name).unwrap();
        // The open arena suggests no goal; cross it diagonally.
        let goal = arena.goal.unwrap_or(Point {
            x_mm: 500.0,
            y_mm: 520.0,
        });
        for seed in 0..3 {
            let robot = RobotModel::khepera_ii();
            let mut world = World::new(arena.clone(), robot.clone(), seed).unwrap();
            let plan = plan_route(&arena, &[], &robot, world.pose(), goal)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            // The path a Guest would define, followed for as long as
            // `vl sim run` gives it by default.
            let mut driver = Driver::to_goal(&world, Some(goal)).unwrap();
            let duration = driver.duration_s();
            let report = run(&mut world, &mut driver, duration);
            let tracking = report.following.unwrap();
            println!(
                "{name:<11} {seed:>4} {:>9.0} {:>8.2} {:>11.1} {:>10.1}",
                plan.length_mm, report.sim_seconds, tracking.mean_error_mm, tracking.max_error_mm
            );
            assert!(tracking.reached_goal, "{name}, seed {seed}: {report:?}");
            assert!(
                report.final_pose.point().distance(goal) <= Goal::DEFAULT_TOLERANCE_MM / 2.0,
                "{name}, seed {seed}: {report:?}"
            );
            assert_eq!(report.collisions, 0, "{name}, seed {seed}: {report:?}");
            assert!(
                tracking.mean_error_mm < 10.0,
                "{name}, seed {seed}: {tracking:?}"
            );
            assert!(
                tracking.max_error_mm < 25.0,
                "{name}, seed {seed}: {tracking:?}"
            );
        }
    }
}
