//! The lab in 3D: the arena's floor, walls and obstacles, the definition's
//! virtual obstacles, the planned path and the forecast's seeds, and the
//! robot's body from its geometry; and the floor as grids, the map the
//! camera made and the C-space the planner and the safety layer use.

use serde_json::Value;
use vl_core::{ARENA_CELL_MM, Arena, Definition, Grid, Point, RobotModel, Shape, disc_cspace};

use super::messages::{
    self, ArrowPrimitive, Base64, Color, CubePrimitive, CylinderPrimitive, LinePrimitive,
    PackedElementField, Quaternion, SceneEntity, SceneUpdate, Time, Vector2, Vector3, rgba,
};
use super::{ARENA_FRAME, MM, ROBOT_FRAME, json, pose, position};

/// How tall the robot's body and the obstacles are drawn, m.
const BODY_M: f64 = 0.03;

fn cube(low: Point, high: Point, height_m: f64, color: Color) -> CubePrimitive {
    let centre = Point {
        x_mm: (low.x_mm + high.x_mm) / 2.0,
        y_mm: (low.y_mm + high.y_mm) / 2.0,
    };
    CubePrimitive {
        pose: pose(centre, 0.0, height_m / 2.0),
        size: Vector3 {
            x: (high.x_mm - low.x_mm) * MM,
            y: (high.y_mm - low.y_mm) * MM,
            z: height_m,
        },
        color,
    }
}

fn line(points: &[Point], z_m: f64, thickness_px: f64, color: Color) -> LinePrimitive {
    LinePrimitive {
        kind: 0,
        pose: pose(Point::default(), 0.0, z_m),
        thickness: thickness_px,
        scale_invariant: true,
        points: points.iter().map(|&p| position(p, 0.0)).collect(),
        color,
        colors: Vec::new(),
        indices: Vec::new(),
    }
}

/// The robot's body in its own frame: its disc, its two wheels, an arrow
/// along its heading and each proximity sensor where it is mounted.
fn body(ns: u64, robot: &RobotModel) -> SceneEntity {
    let mut entity = SceneEntity::new(ns, "robot", ROBOT_FRAME, true);
    let diameter = 2.0 * robot.radius_mm * MM;
    entity.cylinders.push(CylinderPrimitive {
        pose: pose(Point::default(), 0.0, BODY_M / 2.0 + 0.003),
        size: Vector3 {
            x: diameter,
            y: diameter,
            z: BODY_M,
        },
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: rgba(1.0, 0.6, 0.0, 0.9),
    });
    let wheel_mm = (robot.radius_mm * 0.45).max(4.0);
    for side in [1.0, -1.0] {
        let y_mm = side * robot.wheel_base_mm / 2.0;
        entity.cubes.push(CubePrimitive {
            pose: pose(Point { x_mm: 0.0, y_mm }, 0.0, wheel_mm * MM / 2.0),
            size: Vector3 {
                x: wheel_mm * MM,
                y: 0.004,
                z: wheel_mm * MM,
            },
            color: rgba(0.15, 0.15, 0.15, 1.0),
        });
    }
    entity.arrows.push(ArrowPrimitive {
        pose: pose(Point::default(), 0.0, BODY_M + 0.005),
        shaft_length: robot.radius_mm * MM,
        shaft_diameter: 0.004,
        head_length: 0.5 * robot.radius_mm * MM,
        head_diameter: 0.012,
        color: rgba(0.1, 0.1, 0.1, 1.0),
    });
    for mount in &robot.sensors {
        entity.cubes.push(CubePrimitive {
            pose: pose(
                Point {
                    x_mm: mount.x_mm,
                    y_mm: mount.y_mm,
                },
                mount.angle_rad,
                BODY_M / 2.0,
            ),
            size: Vector3 {
                x: 0.003,
                y: 0.006,
                z: 0.006,
            },
            color: rgba(0.8, 0.1, 0.1, 1.0),
        });
    }
    entity
}

/// The arena's floor and walls, its obstacles, the definition's virtual
/// obstacles (translucent red) and path, the forecast's seeds' paths and
/// the robot's body.
pub(crate) fn scene(
    ns: u64,
    arena: &Arena,
    definition: &Definition,
    seeds: &[Vec<Point>],
    robot: &RobotModel,
) -> Value {
    let corner = Point {
        x_mm: arena.width_mm,
        y_mm: arena.height_mm,
    };
    let mut floor = SceneEntity::new(ns, "floor", ARENA_FRAME, false);
    floor.cubes.push(cube(
        Point::default(),
        corner,
        0.001,
        rgba(0.85, 0.85, 0.8, 1.0),
    ));
    let boxes = |shapes: &mut dyn Iterator<Item = &Shape>, color: Color| -> Vec<CubePrimitive> {
        shapes
            .map(|s| {
                let (low, high) = s.bounds();
                cube(low, high, BODY_M, color)
            })
            .collect()
    };
    let mut obstacles = SceneEntity::new(ns, "obstacles", ARENA_FRAME, false);
    obstacles.cubes = boxes(
        &mut arena.obstacles.iter().map(|o| &o.shape),
        rgba(0.2, 0.2, 0.2, 1.0),
    );
    let mut virtual_obstacles = SceneEntity::new(ns, "virtual_obstacles", ARENA_FRAME, false);
    virtual_obstacles.cubes = boxes(
        &mut definition.virtual_obstacles.iter(),
        rgba(0.9, 0.1, 0.1, 0.4),
    );
    let mut path = SceneEntity::new(ns, "path", ARENA_FRAME, false);
    if definition.path.len() >= 2 {
        path.lines
            .push(line(&definition.path, 0.002, 3.0, rgba(0.1, 0.5, 1.0, 1.0)));
    }
    let mut forecast = SceneEntity::new(ns, "forecast", ARENA_FRAME, false);
    forecast.lines = seeds
        .iter()
        .filter(|seed| seed.len() >= 2)
        .map(|seed| line(seed, 0.003, 1.5, rgba(0.6, 0.2, 0.8, 0.6)))
        .collect();
    json(&SceneUpdate {
        deletions: Vec::new(),
        entities: vec![
            floor,
            obstacles,
            virtual_obstacles,
            path,
            forecast,
            body(ns, robot),
        ],
    })
}

/// A grid as Foxglove's: one byte a cell, 0 free and 100 taken (ROS's
/// occupancy values, which the 3D panel's map colours show), rows from
/// the floor's y = 0 up; a little above the floor at `z_m`.
fn grid(ns: u64, grid: &Grid, z_m: f64) -> Value {
    let width = grid.width as usize;
    let mut data = Vec::with_capacity(grid.blocked.len());
    // `Grid` keeps its top row first; Foxglove's rows go along +y.
    for row in grid.blocked.chunks(width).rev() {
        data.extend(row.iter().map(|&b| if b { 100u8 } else { 0 }));
    }
    json(&messages::Grid {
        timestamp: Time::at(ns),
        frame_id: ARENA_FRAME.into(),
        pose: messages::Pose {
            position: Vector3 {
                x: 0.0,
                y: 0.0,
                z: z_m,
            },
            orientation: Quaternion::about_z(0.0),
        },
        column_count: grid.width,
        cell_size: Vector2 {
            x: grid.cell_mm * MM,
            y: grid.cell_mm * MM,
        },
        row_stride: grid.width,
        cell_stride: 1,
        fields: vec![PackedElementField {
            name: "occupancy".into(),
            offset: 0,
            kind: 1,
        }],
        data: Base64(data),
    })
}

/// The map the camera made of the floor (what is dark and not the robot).
pub(crate) fn map_grid(ns: u64, arena: &Arena) -> Option<Value> {
    let map = Grid::from_arena(arena, ARENA_CELL_MM).ok()?;
    Some(grid(ns, &map, 0.0015))
}

/// Where the robot's centre may not go: the map and the definition's
/// virtual obstacles grown by the robot's radius.
pub(crate) fn cspace_grid(
    ns: u64,
    arena: &Arena,
    definition: &Definition,
    robot: &RobotModel,
) -> Option<Value> {
    let cspace = disc_cspace(arena, &definition.virtual_obstacles, robot.radius_mm).ok()?;
    Some(grid(ns, cspace.grid(), 0.001))
}
