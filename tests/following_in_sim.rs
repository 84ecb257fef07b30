//! Path following in the simulator: in every shipped arena, a path planned
//! on the arena's map brings the simulated Khepera to the goal without a
//! collision, and the robot keeps close to the path all the way.

use vl_core::arena::Arena;
use vl_core::follow::{Follower, Following, PLAN_MARGIN_MM};
use vl_core::plan::plan_in_arena;
use vl_core::robot::{Point, RobotModel};
use vl_sim::World;
use vl_sim::script::{Driver, run};

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
            let plan = plan_in_arena(
                &arena,
                &[],
                robot.radius_mm,
                PLAN_MARGIN_MM,
                world.pose(),
                goal,
            )
            .unwrap_or_else(|e| panic!("{name}: {e}"));
            let path = plan.points();
            let follower = Follower::new(path, Following::default()).unwrap();
            let report = run(&mut world, &mut Driver::Path(follower), 120.0);
            let tracking = report.following.unwrap();
            println!(
                "{name:<11} {seed:>4} {:>9.0} {:>8.2} {:>11.1} {:>10.1}",
                plan.length_mm, report.sim_seconds, tracking.mean_error_mm, tracking.max_error_mm
            );
            assert!(tracking.reached_goal, "{name}, seed {seed}: {report:?}");
            assert!(
                report.final_pose.point().distance(goal) <= Following::default().tolerance_mm,
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
