//! The map from the camera: an arena rendered by the simulated camera,
//! binarised, the robot's blob removed and the floor's cells read through
//! the camera model, gives the same occupancy and C-space as the arena's
//! model, up to the pixel boundary: occupancy cells differ only within one
//! cell of an obstacle's edge or the floor's, C-space cells only within a
//! cell's and a pixel's diagonal of where the body would touch.

use proptest::prelude::*;
use vl_core::{
    ARENA_CELL_MM, Arena, CSpace, CameraModel, Footprint, Grid, Material, Obstacle, Point, Pose,
    RobotModel, Shape, look,
};
use vl_sim::{Optics, World, camera_for};

/// How far `p` is from the nearest edge of an obstacle or of the floor, mm.
fn to_nearest_edge(arena: &Arena, p: Point) -> f64 {
    let floor = p
        .x_mm
        .min(arena.width_mm - p.x_mm)
        .min(p.y_mm)
        .min(arena.height_mm - p.y_mm);
    arena
        .obstacles
        .iter()
        .map(|o| o.shape.distance(p).abs())
        .fold(floor, f64::min)
}

/// The largest floor pixel of the cameras below: 1.25 mm straight down,
/// up to about 1.45 mm on the far side tilted 0.4 rad.
const MAX_PIXEL_MM: f64 = 1.5;

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        (0.0f64..700.0, 0.0f64..500.0, 10.0f64..200.0, 10.0f64..200.0).prop_map(
            |(x_mm, y_mm, width_mm, height_mm)| Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm
            }
        ),
        (0.0f64..800.0, 0.0f64..600.0, 8.0f64..90.0).prop_map(|(x_mm, y_mm, radius_mm)| {
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            }
        }),
    ]
}

/// An 800 × 600 mm floor with up to six obstacles and the robot somewhere
/// clear of them.
fn arena() -> impl Strategy<Value = Arena> {
    (
        prop::collection::vec(shape(), 0..6),
        0.0f64..1.0,
        0.0f64..1.0,
        -3.1f64..3.1,
    )
        .prop_filter_map("the robot needs room", |(shapes, fx, fy, theta_rad)| {
            let mut arena = Arena {
                name: "random".into(),
                width_mm: 800.0,
                height_mm: 600.0,
                obstacles: shapes.into_iter().map(Obstacle::from).collect(),
                walls: Material::default(),
                start: Pose::default(),
                goal: None,
            };
            // The robot stands where it has room: 20 mm beyond its body.
            let start = Point {
                x_mm: 60.0 + fx * 680.0,
                y_mm: 60.0 + fy * 480.0,
            };
            arena.is_free(start, 55.0).then(|| {
                arena.start = Pose {
                    x_mm: start.x_mm,
                    y_mm: start.y_mm,
                    theta_rad,
                };
                arena
            })
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The occupancy grid and the C-space of the disc robot, from an ideal
    /// overhead camera and from a tilted one, match the model's.
    #[test]
    fn the_camera_s_map_is_the_model_s_up_to_the_pixel_boundary(arena in arena(), tilt in prop_oneof![Just(0.0), 0.1f64..0.4]) {
        let robot = RobotModel::khepera_ii();
        let world = World::new(arena.clone(), robot.clone(), 1).unwrap();
        let nominal = camera_for(&world, 640, 15.0);
        let optics = Optics { tilt_rad: tilt, ..Optics::default() };
        // The lab knows its camera: here, exactly.
        let camera: CameraModel = optics.view(&nominal, arena.width_mm, arena.height_mm);
        let frame = world.render(&nominal, &optics);
        let seen = look(&frame, &camera);
        let found = seen.robot.expect("the robot is in view");
        prop_assert!(found.point().distance(arena.start.point()) < 1.5, "robot at {found:?}, truly {:?}", arena.start);
        prop_assert!(vl_core::wrap_angle(found.theta_rad - arena.start.theta_rad).abs() < 0.05);
        let from_camera = seen.obstacles(&camera, arena.width_mm, arena.height_mm, ARENA_CELL_MM).unwrap();
        let from_model = Grid::from_arena(&arena, ARENA_CELL_MM).unwrap();
        for r in 0..from_model.height {
            for c in 0..from_model.width {
                if from_camera.is_blocked(c, r) != from_model.is_blocked(c, r) {
                    let edge = to_nearest_edge(&arena, from_model.centre(c, r));
                    prop_assert!(edge <= ARENA_CELL_MM, "cell ({c}, {r}) differs {edge:.1} mm from any edge");
                }
            }
        }
        let disc = Footprint::Disc { radius_mm: robot.radius_mm };
        let c_camera = CSpace::build(&from_camera, disc.clone(), 1).unwrap();
        let c_model = CSpace::build(&from_model, disc, 1).unwrap();
        // The C-space's edge is where the body touches: clearance = radius.
        // Each map quantises it: the model's cells by up to a cell's
        // diagonal (an obstacle's corner can lie that far from the nearest
        // cell centre inside it), the camera's by a pixel's diagonal more.
        // Beyond that band the two C-spaces agree.
        let band = std::f64::consts::SQRT_2 * (ARENA_CELL_MM + MAX_PIXEL_MM);
        let (cg, mg) = (c_camera.grid(), c_model.grid());
        for r in 0..mg.height {
            for c in 0..mg.width {
                if cg.is_blocked(c, r) != mg.is_blocked(c, r) {
                    let off = (arena.clearance(mg.centre(c, r)) - robot.radius_mm).abs();
                    prop_assert!(off <= band, "C-space cell ({c}, {r}) differs {off:.1} mm from the edge");
                }
            }
        }
        // The robot's own blob is not an obstacle.
        let (c, r) = (
            (arena.start.x_mm / ARENA_CELL_MM) as u32,
            from_camera.height - 1 - (arena.start.y_mm / ARENA_CELL_MM) as u32,
        );
        prop_assert!(!from_camera.is_blocked(c, r));
        // And the arena made of it blocks exactly those cells.
        let rebuilt = Grid::from_arena(&vl_core::arena_of(&from_camera, "seen", seen.robot), ARENA_CELL_MM).unwrap();
        prop_assert_eq!(rebuilt.blocked, from_camera.blocked);
    }
}

/// A frame with the robot painted out (as on-change frames are sent)
/// shows the floor where the robot was: nothing of its body or of its
/// light marker is left (the marker is a hole in the body's blob, and was
/// once left behind as a white diamond).
#[test]
fn the_painted_out_robot_leaves_only_floor() {
    for optics in [Optics::default(), Optics::noisy(5)] {
        let arena = Arena::navigation();
        let robot = RobotModel::khepera_ii();
        let world = World::new(arena.clone(), robot.clone(), 1).unwrap();
        let nominal = camera_for(&world, 640, 15.0);
        let camera = optics.view(&nominal, arena.width_mm, arena.height_mm);
        let mut frame = world.render(&nominal, &optics);
        let seen = look(&frame, &camera);
        assert!(seen.robot.is_some());
        seen.erase_robot(&mut frame);
        // Nothing over the body is brighter than the floor beside it (the
        // marker is white) or darker (the body is red).
        let (c, r) = camera.to_pixel(arena.start.point());
        let reach = (robot.radius_mm / camera.mm_per_px()).ceil() as i64;
        let patch = |dc0: i64| {
            let mut grey: Vec<u32> = (-reach..=reach)
                .flat_map(|dr| (-reach..=reach).map(move |dc| (dc, dr)))
                .map(|(dc, dr)| {
                    frame
                        .get_pixel((c as i64 + dc0 + dc) as u32, (r as i64 + dr) as u32)
                        .0
                })
                .map(|p| p.iter().map(|&v| u32::from(v)).sum::<u32>() / 3)
                .collect();
            grey.sort_unstable();
            (grey[0], grey[grey.len() - 1])
        };
        let (body, floor) = (patch(0), patch(3 * reach));
        // The floor beside lies further from the lamp: up to 5 grey levels
        // darker under the noisy camera's lighting gradient.
        assert!(
            body.1 <= floor.1 + 8 && body.0 + 8 >= floor.0,
            "grey over the painted-out robot {body:?}, over the floor beside it {floor:?}"
        );
    }
}
