//! The Foxglove schemas a recording's views use, and those views made from
//! the lab's messages, so Foxglove and Lichtblick show a run with no set-up:
//! the camera, the path drawn over it, the robot's pose in 3D, the arena,
//! its obstacles and the path as a scene, and the Host's log.
//!
//! Foxglove's 3D panel works in metres; the lab in mm. Everything here
//! converts, and only here.

use serde_json::{Value, json};
use vl_core::{Arena, CameraModel, Definition, Point, Pose, RobotModel, Shape};

/// The arena's frame, and the robot's (for transforms and the body).
pub(crate) const ARENA_FRAME: &str = "arena";
pub(crate) const ROBOT_FRAME: &str = "robot";
pub(crate) const CAMERA_FRAME: &str = "camera";

const MM: f64 = 1e-3;

/// A Foxglove schema: its name, which the panels recognise, and its JSON Schema.
pub struct Schema {
    pub name: &'static str,
    pub body: Value,
}

fn object(properties: Value) -> Value {
    let required: Vec<&String> = properties
        .as_object()
        .map_or(vec![], |o| o.keys().collect());
    json!({"type": "object", "properties": properties, "required": required})
}

fn time() -> Value {
    object(
        json!({"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}}),
    )
}

fn vector3() -> Value {
    object(json!({"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}))
}

fn quaternion() -> Value {
    object(
        json!({"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}),
    )
}

fn pose() -> Value {
    object(json!({"position": vector3(), "orientation": quaternion()}))
}

fn color() -> Value {
    object(
        json!({"r": {"type": "number"}, "g": {"type": "number"}, "b": {"type": "number"}, "a": {"type": "number"}}),
    )
}

fn array(items: Value) -> Value {
    json!({"type": "array", "items": items})
}

fn string() -> Value {
    json!({"type": "string"})
}

fn number() -> Value {
    json!({"type": "number"})
}

pub(crate) fn compressed_image() -> Schema {
    Schema {
        name: "foxglove.CompressedImage",
        body: object(json!({
            "timestamp": time(),
            "frame_id": string(),
            "data": {"type": "string", "contentEncoding": "base64"},
            "format": string(),
        })),
    }
}

pub(crate) fn pose_in_frame() -> Schema {
    Schema {
        name: "foxglove.PoseInFrame",
        body: object(json!({"timestamp": time(), "frame_id": string(), "pose": pose()})),
    }
}

pub(crate) fn frame_transform() -> Schema {
    Schema {
        name: "foxglove.FrameTransform",
        body: object(json!({
            "timestamp": time(),
            "parent_frame_id": string(),
            "child_frame_id": string(),
            "translation": vector3(),
            "rotation": quaternion(),
        })),
    }
}

pub(crate) fn log() -> Schema {
    Schema {
        name: "foxglove.Log",
        body: object(json!({
            "timestamp": time(),
            "level": {"type": "integer", "minimum": 0, "maximum": 5},
            "message": string(),
            "name": string(),
            "file": string(),
            "line": {"type": "integer", "minimum": 0},
        })),
    }
}

pub(crate) fn image_annotations() -> Schema {
    let point2 = object(json!({"x": number(), "y": number()}));
    let points = object(json!({
        "timestamp": time(),
        "type": {"type": "integer", "minimum": 0, "maximum": 4},
        "points": array(point2.clone()),
        "outline_color": color(),
        "outline_colors": array(color()),
        "fill_color": color(),
        "thickness": number(),
    }));
    let circle = object(json!({
        "timestamp": time(),
        "position": point2.clone(),
        "diameter": number(),
        "thickness": number(),
        "fill_color": color(),
        "outline_color": color(),
    }));
    let text = object(json!({
        "timestamp": time(),
        "position": point2,
        "text": string(),
        "font_size": number(),
        "text_color": color(),
        "background_color": color(),
    }));
    Schema {
        name: "foxglove.ImageAnnotations",
        body: object(
            json!({"circles": array(circle), "points": array(points), "texts": array(text)}),
        ),
    }
}

pub(crate) fn scene_update() -> Schema {
    let cube = object(json!({"pose": pose(), "size": vector3(), "color": color()}));
    let cylinder = object(json!({
        "pose": pose(), "size": vector3(), "bottom_scale": number(), "top_scale": number(), "color": color(),
    }));
    let line = object(json!({
        "type": {"type": "integer", "minimum": 0, "maximum": 2},
        "pose": pose(),
        "thickness": number(),
        "scale_invariant": {"type": "boolean"},
        "points": array(vector3()),
        "color": color(),
        "colors": array(color()),
        "indices": array(json!({"type": "integer", "minimum": 0})),
    }));
    let entity = object(json!({
        "timestamp": time(),
        "frame_id": string(),
        "id": string(),
        "lifetime": object(json!({"sec": {"type": "integer"}, "nsec": {"type": "integer"}})),
        "frame_locked": {"type": "boolean"},
        "metadata": array(object(json!({"key": string(), "value": string()}))),
        "cubes": array(cube),
        "cylinders": array(cylinder),
        "lines": array(line),
    }));
    let deletion =
        object(json!({"timestamp": time(), "type": {"type": "integer"}, "id": string()}));
    Schema {
        name: "foxglove.SceneUpdate",
        body: object(json!({"deletions": array(deletion), "entities": array(entity)})),
    }
}

/// Foxglove's time from nanoseconds since 1970.
pub(crate) fn stamp(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn rotation(theta_rad: f64) -> Value {
    json!({"x": 0.0, "y": 0.0, "z": (theta_rad / 2.0).sin(), "w": (theta_rad / 2.0).cos()})
}

fn position(p: Point, z_m: f64) -> Value {
    json!({"x": p.x_mm * MM, "y": p.y_mm * MM, "z": z_m})
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Value {
    json!({"r": r, "g": g, "b": b, "a": a})
}

pub(crate) fn image(ns: u64, jpeg: &[u8]) -> Value {
    use base64::Engine;
    json!({
        "timestamp": stamp(ns),
        "frame_id": CAMERA_FRAME,
        "data": base64::engine::general_purpose::STANDARD.encode(jpeg),
        "format": "jpeg",
    })
}

pub(crate) fn pose_message(ns: u64, pose: Pose) -> Value {
    json!({
        "timestamp": stamp(ns),
        "frame_id": ARENA_FRAME,
        "pose": {"position": position(pose.point(), 0.0), "orientation": rotation(pose.theta_rad)},
    })
}

pub(crate) fn transform(ns: u64, pose: Pose) -> Value {
    json!({
        "timestamp": stamp(ns),
        "parent_frame_id": ARENA_FRAME,
        "child_frame_id": ROBOT_FRAME,
        "translation": position(pose.point(), 0.0),
        "rotation": rotation(pose.theta_rad),
    })
}

/// Foxglove's log levels: 1 debug … 5 fatal.
#[derive(Debug, Clone, Copy)]
pub enum Level {
    Info = 2,
    Warning = 3,
}

pub(crate) fn log_message(ns: u64, level: Level, text: &str) -> Value {
    json!({
        "timestamp": stamp(ns),
        "level": level as u8,
        "message": text,
        "name": "vl host",
        "file": "",
        "line": 0,
    })
}

/// The planned path over the camera image, and the robot where it is
/// believed to be, in the image's pixels.
pub(crate) fn annotations(
    ns: u64,
    camera: &CameraModel,
    path: &[Point],
    robot: Option<(Pose, f64)>,
) -> Value {
    let pixel = |p: Point| {
        let (x, y) = camera.to_pixel(p);
        json!({"x": x, "y": y})
    };
    let mut points = Vec::new();
    if path.len() >= 2 {
        points.push(json!({
            "timestamp": stamp(ns),
            "type": 2,
            "points": path.iter().map(|&p| pixel(p)).collect::<Vec<_>>(),
            "outline_color": rgba(0.1, 0.5, 1.0, 1.0),
            "outline_colors": [],
            "fill_color": rgba(0.0, 0.0, 0.0, 0.0),
            "thickness": 2.0,
        }));
    }
    let circles: Vec<Value> = robot
        .map(|(pose, radius_mm)| {
            let (x, y) = camera.to_pixel(pose.point());
            json!({
                "timestamp": stamp(ns),
                "position": {"x": x, "y": y},
                "diameter": 2.0 * radius_mm / camera.mm_per_px(),
                "thickness": 2.0,
                "fill_color": rgba(0.0, 0.0, 0.0, 0.0),
                "outline_color": rgba(1.0, 0.6, 0.0, 1.0),
            })
        })
        .into_iter()
        .collect();
    json!({"circles": circles, "points": points, "texts": []})
}

fn cube(low: Point, high: Point, height_m: f64, color: Value) -> Value {
    let centre = Point {
        x_mm: (low.x_mm + high.x_mm) / 2.0,
        y_mm: (low.y_mm + high.y_mm) / 2.0,
    };
    json!({
        "pose": {"position": position(centre, height_m / 2.0), "orientation": rotation(0.0)},
        "size": {"x": (high.x_mm - low.x_mm) * MM, "y": (high.y_mm - low.y_mm) * MM, "z": height_m},
        "color": color,
    })
}

fn entity(
    ns: u64,
    id: &str,
    frame: &str,
    cubes: Vec<Value>,
    cylinders: Vec<Value>,
    lines: Vec<Value>,
) -> Value {
    json!({
        "timestamp": stamp(ns),
        "frame_id": frame,
        "id": id,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": frame == ROBOT_FRAME,
        "metadata": [],
        "cubes": cubes,
        "cylinders": cylinders,
        "lines": lines,
    })
}

/// The arena's floor and walls, its obstacles, the definition's virtual
/// obstacles (translucent red) and path, and the robot's body.
pub(crate) fn scene(ns: u64, arena: &Arena, definition: &Definition, robot: &RobotModel) -> Value {
    let floor = cube(
        Point {
            x_mm: 0.0,
            y_mm: 0.0,
        },
        Point {
            x_mm: arena.width_mm,
            y_mm: arena.height_mm,
        },
        0.001,
        rgba(0.85, 0.85, 0.8, 1.0),
    );
    let boxes = |shapes: &mut dyn Iterator<Item = &Shape>, color: Value| -> Vec<Value> {
        shapes
            .map(|s| {
                let (low, high) = s.bounds();
                cube(low, high, 0.03, color.clone())
            })
            .collect()
    };
    let obstacles = boxes(
        &mut arena.obstacles.iter().map(|o| &o.shape),
        rgba(0.2, 0.2, 0.2, 1.0),
    );
    let virtual_obstacles = boxes(
        &mut definition.virtual_obstacles.iter(),
        rgba(0.9, 0.1, 0.1, 0.4),
    );
    let path = json!({
        "type": 0,
        "pose": {"position": position(Point::default(), 0.002), "orientation": rotation(0.0)},
        "thickness": 3.0,
        "scale_invariant": true,
        "points": definition.path.iter().map(|&p| position(p, 0.0)).collect::<Vec<_>>(),
        "color": rgba(0.1, 0.5, 1.0, 1.0),
        "colors": [],
        "indices": [],
    });
    let diameter = 2.0 * robot.radius_mm * MM;
    let body = json!({
        "pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.015}, "orientation": rotation(0.0)},
        "size": {"x": diameter, "y": diameter, "z": 0.03},
        "bottom_scale": 1.0,
        "top_scale": 1.0,
        "color": rgba(1.0, 0.6, 0.0, 1.0),
    });
    json!({
        "deletions": [],
        "entities": [
            entity(ns, "floor", ARENA_FRAME, vec![floor], vec![], vec![]),
            entity(ns, "obstacles", ARENA_FRAME, obstacles, vec![], vec![]),
            entity(ns, "virtual_obstacles", ARENA_FRAME, virtual_obstacles, vec![], vec![]),
            entity(ns, "path", ARENA_FRAME, vec![], vec![], vec![path]),
            entity(ns, "robot", ROBOT_FRAME, vec![], vec![body], vec![]),
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every message made here has every field its schema requires.
    fn has_required(schema: &Value, message: &Value) {
        if let Some(required) = schema.get("required").and_then(Value::as_array) {
            for key in required {
                let key = key.as_str().unwrap();
                let field = message
                    .get(key)
                    .unwrap_or_else(|| panic!("{key} missing from {message}"));
                has_required(&schema["properties"][key], field);
            }
        }
        if let (Some(items), Some(values)) = (schema.get("items"), message.as_array()) {
            for value in values {
                has_required(items, value);
            }
        }
    }

    #[test]
    fn messages_carry_what_their_schemas_require() {
        let arena = Arena::navigation();
        let camera = CameraModel::overhead(400.0, 300.0, 320, 15.0);
        let pose = Pose {
            x_mm: 100.0,
            y_mm: 50.0,
            theta_rad: 1.0,
        };
        let definition = Definition {
            path: vec![
                pose.point(),
                Point {
                    x_mm: 200.0,
                    y_mm: 80.0,
                },
            ],
            ..Definition::default()
        };
        let robot = RobotModel::khepera_ii();
        let cases = [
            (compressed_image(), image(5, &[1, 2, 3])),
            (pose_in_frame(), pose_message(5, pose)),
            (frame_transform(), transform(5, pose)),
            (log(), log_message(5, Level::Info, "run 1 started")),
            (
                image_annotations(),
                annotations(5, &camera, &definition.path, Some((pose, 35.0))),
            ),
            (scene_update(), scene(5, &arena, &definition, &robot)),
        ];
        for (schema, message) in cases {
            has_required(&schema.body, &message);
        }
    }

    #[test]
    fn a_heading_is_a_rotation_about_z() {
        let q = rotation(std::f64::consts::PI);
        assert!((q["z"].as_f64().unwrap() - 1.0).abs() < 1e-12);
        assert!(q["w"].as_f64().unwrap().abs() < 1e-12);
    }
}
