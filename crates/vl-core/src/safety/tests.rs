//! The safety layer's tests: its checks, and closed loops of random driving
//! through it, the Host freezing at any moment.

use super::*;
use crate::WheelMove;
use proptest::prelude::*;

fn open_arena() -> Arena {
    Arena::load("open").unwrap()
}

fn at(x_mm: f64, y_mm: f64, theta_rad: f64) -> Pose {
    Pose {
        x_mm,
        y_mm,
        theta_rad,
    }
}

/// Told to go on at `wheels`, from where the robot is.
fn going(robot: &RobotModel, wheels: WheelSpeeds) -> Told {
    Told::Leash {
        leash: Leash::new(robot, wheels, 0.03, wheels, 0.0),
        from_mm: [0.0; 2],
    }
}

fn ahead(v: f64) -> WheelSpeeds {
    WheelSpeeds {
        left_mm_s: v,
        right_mm_s: v,
    }
}

#[test]
fn full_speed_at_a_wall_slows_in_time_and_backing_off_is_free() {
    let arena = open_arena();
    let robot = RobotModel::khepera_ii();
    let s = Surroundings::new(&arena);
    let safety = Safety::default();
    let facing_wall = |gap: f64, speed: f64| Situation {
        pose: at(arena.width_mm - robot.radius_mm - gap, 300.0, 0.0),
        wheels: ahead(speed),
        told: going(&robot, ahead(speed)),
        proximity: &[],
    };
    // At full speed the robot brakes by itself in 650 mm.
    let far = safety.guard(&robot, &s, facing_wall(700.0, 1016.0), ahead(1016.0));
    assert!(!far.limited, "{far:?}");
    // At 200 mm/s, 50 mm out: speeding up would not leave room to brake,
    // carrying on more slowly does.
    let near = safety.guard(&robot, &s, facing_wall(50.0, 200.0), ahead(1000.0));
    assert!(near.limited && near.wheels.left_mm_s > 0.0, "{near:?}");
    assert!(near.wheels.left_mm_s < 300.0, "{near:?}");
    // At 500 mm/s, 50 mm out, no leash stops clear: the wheels stop at once.
    let late = safety.guard(&robot, &s, facing_wall(50.0, 500.0), ahead(1000.0));
    assert!(late.leash.is_stop(), "{late:?}");
    let facing_wall = |gap: f64| facing_wall(gap, 0.0);
    let touching = safety.guard(&robot, &s, facing_wall(1.0), ahead(300.0));
    assert_eq!(touching.wheels, WheelSpeeds::default(), "{touching:?}");
    let back = safety.guard(&robot, &s, facing_wall(1.0), ahead(-300.0));
    assert!(!back.limited, "moving away is always allowed: {back:?}");
    let spin = WheelSpeeds {
        left_mm_s: -200.0,
        right_mm_s: 200.0,
    };
    assert!(!safety.guard(&robot, &s, facing_wall(1.0), spin).limited);
}

#[test]
fn virtual_obstacles_are_walls_to_the_layer() {
    let arena = open_arena();
    let robot = RobotModel::khepera_ii();
    let block = Shape::Circle {
        x_mm: 400.0,
        y_mm: 300.0,
        radius_mm: 20.0,
    };
    let s = Surroundings::new(&arena).with(std::slice::from_ref(&block));
    let p = Point {
        x_mm: 400.0 - 20.0 - robot.radius_mm - 6.0,
        y_mm: 300.0,
    };
    assert_eq!(s.clearance(p), block.distance(p));
    let situation = Situation {
        pose: at(p.x_mm, p.y_mm, 0.0),
        wheels: WheelSpeeds::default(),
        told: Told::Stop,
        proximity: &[],
    };
    let g = Safety::default().guard(&robot, &s, situation, ahead(500.0));
    assert!(g.limited && g.wheels.left_mm_s < 100.0, "{g:?}");
}

#[test]
fn what_the_sensors_see_counts_as_an_obstacle() {
    let arena = open_arena();
    let robot = RobotModel::khepera_ii();
    let s = Surroundings::new(&arena);
    // The two front sensors see something 10 mm ahead that no map shows.
    let mut proximity = vec![0; 8];
    proximity[2] = ir_reading(10.0) as u16;
    proximity[3] = ir_reading(10.0) as u16;
    let situation = Situation {
        pose: at(300.0, 300.0, 0.0),
        wheels: WheelSpeeds::default(),
        told: Told::Stop,
        proximity: &proximity,
    };
    let g = Safety::default().guard(&robot, &s, situation, ahead(500.0));
    assert!(g.wheels.left_mm_s < 1.0, "{g:?}");
}

#[test]
fn numbers_that_are_not_speeds_stop_the_robot() {
    let arena = open_arena();
    let robot = RobotModel::khepera_ii();
    let s = Surroundings::new(&arena);
    let situation = Situation {
        pose: at(300.0, 300.0, 0.0),
        wheels: WheelSpeeds::default(),
        told: Told::Stop,
        proximity: &[],
    };
    let nan = WheelSpeeds {
        left_mm_s: f64::NAN,
        right_mm_s: 1.0,
    };
    let g = Safety::default().guard(&robot, &s, situation, nan);
    assert_eq!(g.wheels, WheelSpeeds::default());
}

/// A shipped arena and the point (fx, fy) of the way across it, where
/// the Khepera II stands clear of everything, if it does.
fn standing(name: &str, fx: f64, fy: f64) -> Option<(Arena, RobotModel, Point)> {
    let arena = Arena::load(name).unwrap();
    let robot = RobotModel::khepera_ii();
    let p = Point {
        x_mm: fx * arena.width_mm,
        y_mm: fy * arena.height_mm,
    };
    arena
        .is_free(p, robot.radius_mm + 1.0)
        .then_some((arena, robot, p))
}

proptest! {
    /// Whatever is asked, wherever the robot is and however fast it
    /// goes, driving the guarded command and then braking never brings
    /// the body nearer than the margin, or nearer than it already was.
    #[test]
    fn guarded_commands_always_stop_in_time(
        fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
        vl in -1100.0f64..1100.0, vr in -1100.0f64..1100.0,
        wl in -1100.0f64..1100.0, wr in -1100.0f64..1100.0,
        arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
    ) {
        let standing = standing(arena, fx, fy);
        prop_assume!(standing.is_some());
        let (arena, robot, p) = standing.unwrap();
        let s = Surroundings::new(&arena);
        let safety = Safety::default();
        let wheels = robot.clamp(WheelSpeeds { left_mm_s: vl, right_mm_s: vr });
        let situation = Situation {
            pose: at(p.x_mm, p.y_mm, theta),
            wheels,
            told: going(&robot, wheels),
            proximity: &[],
        };
        let g = safety.guard(&robot, &s, situation, WheelSpeeds { left_mm_s: wl, right_mm_s: wr });
        let now = arena.clearance(p) - robot.radius_mm;
        // The moving robot may already be past saving; then the layer
        // stops it and nothing more can be asked of it.
        prop_assume!(g.wheels != WheelSpeeds::default() || !g.limited);
        let floor = safety.margin_mm.min(now) - 1e-6;
        let exact = |pose: Pose| arena.clearance(pose.point()) - robot.radius_mm;
        prop_assert!(safety.leash_clear(&robot, situation, g.leash, exact, floor), "{:?} from {:?}", g, situation.pose);
    }

    /// Closed loop: a robot at rest anywhere free, driven by random
    /// full-speed commands that change every 0.2 s, each guarded and
    /// its leash followed by the wheels for a 10 ms control period,
    /// never touches anything — nor when, at any period, the Host
    /// freezes and the last leash runs out by itself.
    #[test]
    fn random_driving_through_the_layer_never_touches(
        fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
        commands in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 20),
        freeze in 0usize..400,
        arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
    ) {
        let standing = standing(arena, fx, fy);
        prop_assume!(standing.is_some());
        let (arena, robot, p) = standing.unwrap();
        let s = Surroundings::new(&arena);
        let safety = Safety::default();
        let mut rig = BrakingRig::at(at(p.x_mm, p.y_mm, theta));
        let top = robot.max_wheel_speed_mm_s;
        let clear = |rig: &BrakingRig| arena.clearance(rig.pose.point()) - robot.radius_mm;
        for tick in 0..400 {
            let (l, r) = commands[tick / 20];
            let wanted = WheelSpeeds { left_mm_s: l * top, right_mm_s: r * top };
            let situation = Situation { pose: rig.pose, wheels: rig.wheels, told: rig.told(), proximity: &[] };
            let g = safety.guard(&robot, &s, situation, wanted);
            rig.tell(&robot, g.leash, rig.travel);
            let steps = if tick == freeze { 5000 } else { 5 };
            for _ in 0..steps {
                rig.step(&robot, 0.002);
                prop_assert!(clear(&rig) > 0.0, "touched at {:?} on tick {} (frozen at {})", rig.pose, tick, freeze);
            }
            if tick == freeze {
                prop_assert!(rig.wheels.left_mm_s.abs() < 1.0 && rig.wheels.right_mm_s.abs() < 1.0, "{:?}", rig.wheels);
                break;
            }
        }
    }

    /// The same on a slow serial line: the pose is read at the start of
    /// each control period of up to 120 ms (a 9600-baud Khepera's reads),
    /// and the leash reaches the wheels up to a period later, the
    /// wheels meanwhile following the one before. Told the period and
    /// that delay, the layer still never lets the robot touch anything,
    /// frozen or not.
    #[test]
    fn random_driving_on_a_slow_line_never_touches(
        fx in 0.0f64..1.0, fy in 0.0f64..1.0, theta in -3.2f64..3.2,
        commands in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 8),
        period_steps in 5usize..60, delay_share in 0.0f64..1.0, freeze_share in 0.0f64..1.0,
        arena in proptest::sample::select(vec!["navigation", "corridor", "open", "maze"]),
    ) {
        let standing = standing(arena, fx, fy);
        prop_assume!(standing.is_some());
        let (arena, robot, p) = standing.unwrap();
        let s = Surroundings::new(&arena);
        let delay_steps = (delay_share * period_steps as f64) as usize;
        let safety = Safety {
            hold_s: 1.5 * period_steps as f64 * 0.002,
            delay_s: delay_steps as f64 * 0.002,
            ..Safety::default()
        };
        let mut rig = BrakingRig::at(at(p.x_mm, p.y_mm, theta));
        let top = robot.max_wheel_speed_mm_s;
        let periods = 4000 / period_steps;
        let freeze = (freeze_share * periods as f64) as usize;
        let clear = |rig: &BrakingRig| arena.clearance(rig.pose.point()) - robot.radius_mm;
        for tick in 0..periods {
            let (l, r) = commands[tick * commands.len() / periods];
            let wanted = WheelSpeeds { left_mm_s: l * top, right_mm_s: r * top };
            let situation = Situation { pose: rig.pose, wheels: rig.wheels, told: rig.told(), proximity: &[] };
            let g = safety.guard(&robot, &s, situation, wanted);
            let read_at = rig.travel;
            for _ in 0..delay_steps {
                rig.step(&robot, 0.002);
                prop_assert!(clear(&rig) > 0.0, "touched at {:?} in period {}", rig.pose, tick);
            }
            rig.tell(&robot, g.leash, read_at);
            let steps = if tick == freeze { 5000 } else { period_steps - delay_steps };
            for _ in 0..steps {
                rig.step(&robot, 0.002);
                prop_assert!(clear(&rig) > 0.0, "touched at {:?} in period {} (frozen at {})", rig.pose, tick, freeze);
            }
            if tick == freeze {
                break;
            }
        }
    }
}

#[test]
fn past_a_face_only_coming_out_passes() {
    let arena = open_arena();
    let robot = RobotModel::khepera_ii();
    let s = Surroundings::new(&arena);
    // The estimate says the body is 20 mm into the east wall.
    let situation = Situation {
        pose: at(arena.width_mm - robot.radius_mm + 20.0, 300.0, 0.0),
        wheels: WheelSpeeds::default(),
        told: Told::Stop,
        proximity: &[],
    };
    let safety = Safety::default();
    let deeper = safety.guard(&robot, &s, situation, ahead(1000.0));
    assert_eq!(deeper.wheels, WheelSpeeds::default(), "{deeper:?}");
    assert!(deeper.clearance_mm < -19.0, "{deeper:?}");
    let out = safety.guard(&robot, &s, situation, ahead(-300.0));
    assert!(!out.limited, "{out:?}");
}

#[test]
fn a_late_command_brakes_earlier() {
    let arena = open_arena();
    let robot = RobotModel::khepera_ii();
    let s = Surroundings::new(&arena);
    let gap = 200.0;
    let situation = Situation {
        pose: at(arena.width_mm - robot.radius_mm - gap, 300.0, 0.0),
        wheels: ahead(400.0),
        told: going(&robot, ahead(400.0)),
        proximity: &[],
    };
    let prompt = Safety::default().guard(&robot, &s, situation, ahead(800.0));
    assert!(prompt.wheels.left_mm_s > 400.0, "{prompt:?}");
    let late = Safety {
        delay_s: 0.1,
        hold_s: 0.1,
        ..Safety::default()
    }
    .guard(&robot, &s, situation, ahead(800.0));
    assert!(
        late.wheels.left_mm_s < prompt.wheels.left_mm_s,
        "{late:?} vs {prompt:?}"
    );
}

/// The robot as its firmware moves it: each wheel's controller on its
/// leash's trapezoid (from where the wheel was when the robot was
/// read), or braked by the speed controller.
struct BrakingRig {
    pose: Pose,
    wheels: WheelSpeeds,
    travel: [f64; 2],
    controls: [PositionControl; 2],
    moves: Option<[WheelMove; 2]>,
    /// The last leash and the travel its reach counts from.
    leash: Option<(Leash, [f64; 2])>,
}

impl BrakingRig {
    fn at(pose: Pose) -> BrakingRig {
        BrakingRig {
            pose,
            wheels: WheelSpeeds::default(),
            travel: [0.0; 2],
            controls: [PositionControl::default(); 2],
            moves: None,
            leash: None,
        }
    }

    /// What the wheels were last told, seen from a reading now.
    fn told(&self) -> Told {
        Told::seen_from(self.leash, self.travel)
    }

    fn tell(&mut self, robot: &RobotModel, leash: Leash, read_at: [f64; 2]) {
        let was = self.moves;
        self.moves = (!leash.is_stop()).then(|| leash.moves(robot, read_at));
        self.leash = (!leash.is_stop()).then_some((leash, read_at));
        if was.is_none() {
            let w = [self.wheels.left_mm_s, self.wheels.right_mm_s];
            self.controls = [0, 1].map(|i| PositionControl::taking_over(self.travel[i], w[i]));
        }
    }

    fn step(&mut self, robot: &RobotModel, dt: f64) {
        let mut asked = [0.0; 2];
        if let Some(moves) = self.moves {
            for i in 0..2 {
                asked[i] = self.controls[i].step(&moves[i], self.travel[i], &robot.response, dt);
            }
        }
        let asked = WheelSpeeds {
            left_mm_s: asked[0],
            right_mm_s: asked[1],
        };
        let was = self.wheels;
        (self.pose, self.wheels) = robot.respond(self.pose, self.wheels, asked, dt);
        self.travel[0] += (was.left_mm_s + self.wheels.left_mm_s) / 2.0 * dt;
        self.travel[1] += (was.right_mm_s + self.wheels.right_mm_s) / 2.0 * dt;
    }
}
