//! Numbers from outside cannot hurt the robot: whatever `f64`s a command
//! carries — huge, tiny, infinite, not numbers at all — every conversion on
//! the way to the wheels (the command, the run's speed cap, the assistance
//! of teleoperation, the safety layer, the simulator) leaves them finite
//! and within the robot's limits.

use proptest::prelude::*;
use vl_core::{
    Arena, Drive, Leash, Pose, RobotModel, Safety, Situation, Surroundings, Teleop, Told, Vector,
    WheelSpeeds,
};
use vl_sim::World;

fn any_number() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(1e308),
        Just(-1e308),
        Just(1e307),
        Just(f64::MIN_POSITIVE / 2.0),
        Just(-0.0),
        -2000.0f64..2000.0,
    ]
}

fn within(robot: &RobotModel, w: WheelSpeeds) -> bool {
    let ok = |v: f64| v.is_finite() && v.abs() <= robot.max_wheel_speed_mm_s + 1e-9;
    ok(w.left_mm_s) && ok(w.right_mm_s)
}

proptest! {
    #[test]
    fn any_numbers_reach_the_wheels_finite_and_within_limits(
        a in any_number(), b in any_number(), cap in 1.0f64..2000.0,
        field_x in any_number(), field_y in any_number(),
        velocity in any::<bool>(),
    ) {
        let robot = RobotModel::khepera_ii();
        let drive = if velocity { Drive::Velocity { v: a, w: b } } else { Drive::Wheels { left: a, right: b } };
        // The command, then the run's speed cap.
        let wheels = drive.wheels(&robot);
        prop_assert!(within(&robot, wheels), "{:?} → {:?}", drive, wheels);
        let mut capped = robot.clone();
        capped.max_wheel_speed_mm_s = capped.max_wheel_speed_mm_s.min(cap);
        let wheels = capped.clamp(wheels);
        prop_assert!(within(&robot, wheels));
        // Teleoperation's assistance, with any field.
        let teleop = Teleop::default();
        let v = (wheels.left_mm_s + wheels.right_mm_s) / 2.0;
        let w = (wheels.right_mm_s - wheels.left_mm_s) / robot.wheel_base_mm;
        let assisted = teleop.assist(&robot, teleop.velocity_for(&robot, v, w), Vector { x: field_x, y: field_y });
        prop_assert!(within(&robot, assisted.wheels), "{:?}", assisted);
        prop_assert!(assisted.force.iter().all(|f| f.is_finite()));
        // The safety layer, even from a nonsense situation.
        let arena = Arena::navigation();
        let surroundings = Surroundings::new(&arena);
        let situation = Situation {
            pose: Pose { x_mm: 300.0, y_mm: 300.0, theta_rad: b },
            wheels: WheelSpeeds { left_mm_s: field_x, right_mm_s: field_y },
            told: Told::Leash {
                leash: Leash::new(&robot, WheelSpeeds { left_mm_s: a, right_mm_s: field_x }, b, WheelSpeeds { left_mm_s: field_y, right_mm_s: a }, field_x),
                from_mm: [field_y, b],
            },
            proximity: &[1023, 0, 5, 900, 0, 0, 0, 0],
        };
        let raw = WheelSpeeds { left_mm_s: a, right_mm_s: b };
        let guarded = Safety::default().guard(&robot, &surroundings, situation, raw);
        prop_assert!(within(&robot, guarded.wheels), "{:?}", guarded);
        // The simulator takes any numbers and stays finite.
        let mut world = World::new(arena, robot.clone(), 1).unwrap();
        world.set_wheels(raw);
        world.run_for(0.05);
        prop_assert!(within(&robot, world.wheels()));
        let p = world.pose();
        prop_assert!(p.x_mm.is_finite() && p.y_mm.is_finite() && p.theta_rad.is_finite());
    }
}
