//! The Foxglove schemas a recording's views use, and those views made from
//! the lab's messages, so Foxglove and Lichtblick show a run with no set-up:
//! the camera placed in 3D by its calibration, the path drawn over it, the
//! robot's pose, its sensors and its body, the arena, the camera-built map
//! and the C-space as grids, the planned and forecast paths, and the
//! Host's log.
//!
//! Foxglove's 3D panel works in metres; the lab in mm. Everything here
//! converts, and only here. The messages are typed (`messages`), and their
//! schemas generated from those types.

mod messages;
mod scene;

use serde_json::Value;
use vl_core::{CameraModel, Pinhole, Point, Pose, RobotModel, ir_distance};

use messages::{
    Base64, CameraCalibration, CircleAnnotation, CompressedImage, FrameTransform, ImageAnnotations,
    LaserScan, Log, Point2, PointsAnnotation, PoseInFrame, PosesInFrame, Quaternion, Time, Vector3,
    rgba,
};
pub(crate) use scene::{cspace_grid, map_grid, scene};

/// The arena's frame, the robot's and the camera's (for transforms).
pub(crate) const ARENA_FRAME: &str = "arena";
pub(crate) const ROBOT_FRAME: &str = "robot";
pub(crate) const CAMERA_FRAME: &str = "camera";

const MM: f64 = 1e-3;

/// Each Foxglove schema a view uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    CompressedImage,
    ImageAnnotations,
    PoseInFrame,
    PosesInFrame,
    FrameTransform,
    SceneUpdate,
    Grid,
    CameraCalibration,
    LaserScan,
    Log,
}

impl Kind {
    pub(crate) fn schema(self) -> crate::Schema {
        use crate::schemas::schema_of;
        use messages as m;
        match self {
            Kind::CompressedImage => schema_of::<m::CompressedImage>("foxglove.CompressedImage"),
            Kind::ImageAnnotations => schema_of::<m::ImageAnnotations>("foxglove.ImageAnnotations"),
            Kind::PoseInFrame => schema_of::<m::PoseInFrame>("foxglove.PoseInFrame"),
            Kind::PosesInFrame => schema_of::<m::PosesInFrame>("foxglove.PosesInFrame"),
            Kind::FrameTransform => schema_of::<m::FrameTransform>("foxglove.FrameTransform"),
            Kind::SceneUpdate => schema_of::<m::SceneUpdate>("foxglove.SceneUpdate"),
            Kind::Grid => schema_of::<m::Grid>("foxglove.Grid"),
            Kind::CameraCalibration => {
                schema_of::<m::CameraCalibration>("foxglove.CameraCalibration")
            }
            Kind::LaserScan => schema_of::<m::LaserScan>("foxglove.LaserScan"),
            Kind::Log => schema_of::<m::Log>("foxglove.Log"),
        }
    }
}

fn json<T: serde::Serialize>(message: &T) -> Value {
    serde_json::to_value(message).expect("Foxglove's messages serialise")
}

fn position(p: Point, z_m: f64) -> Vector3 {
    Vector3 {
        x: p.x_mm * MM,
        y: p.y_mm * MM,
        z: z_m,
    }
}

fn pose(p: Point, theta_rad: f64, z_m: f64) -> messages::Pose {
    messages::Pose {
        position: position(p, z_m),
        orientation: Quaternion::about_z(theta_rad),
    }
}

pub(crate) fn image(ns: u64, jpeg: &[u8]) -> Value {
    json(&CompressedImage {
        timestamp: Time::at(ns),
        frame_id: CAMERA_FRAME.into(),
        data: Base64(jpeg.to_vec()),
        format: "jpeg".into(),
    })
}

pub(crate) fn pose_message(ns: u64, robot: Pose) -> Value {
    json(&PoseInFrame {
        timestamp: Time::at(ns),
        frame_id: ARENA_FRAME.into(),
        pose: pose(robot.point(), robot.theta_rad, 0.0),
    })
}

/// Where the robot is: the arena → robot transform.
pub(crate) fn transform(ns: u64, robot: Pose) -> Value {
    json(&FrameTransform {
        timestamp: Time::at(ns),
        parent_frame_id: ARENA_FRAME.into(),
        child_frame_id: ROBOT_FRAME.into(),
        translation: position(robot.point(), 0.0),
        rotation: Quaternion::about_z(robot.theta_rad),
    })
}

/// Where the camera is: the arena → camera transform, from its calibration.
pub(crate) fn camera_transform(ns: u64, pinhole: &Pinhole) -> Value {
    let [x, y, z] = pinhole.position_mm;
    let q = pinhole.orientation.quaternion();
    json(&FrameTransform {
        timestamp: Time::at(ns),
        parent_frame_id: ARENA_FRAME.into(),
        child_frame_id: CAMERA_FRAME.into(),
        translation: Vector3 {
            x: x * MM,
            y: y * MM,
            z: z * MM,
        },
        rotation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    })
}

/// The camera's intrinsics and lens, for the image's frame.
pub(crate) fn calibration(ns: u64, pinhole: &Pinhole) -> Value {
    json(&CameraCalibration {
        timestamp: Time::at(ns),
        frame_id: CAMERA_FRAME.into(),
        width: pinhole.width_px,
        height: pinhole.height_px,
        distortion_model: "plumb_bob".into(),
        D: pinhole.plumb_bob.to_vec(),
        K: pinhole.k(),
        R: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        P: pinhole.p(),
    })
}

/// A path as poses in the arena, each heading along the path.
pub(crate) fn path_poses(ns: u64, path: &[Point]) -> Value {
    let heading = |i: usize| {
        let (a, b) = match (path.get(i), path.get(i + 1)) {
            (Some(&a), Some(&b)) => (a, b),
            _ if i > 0 => (path[i - 1], path[i]),
            _ => return 0.0,
        };
        (b.y_mm - a.y_mm).atan2(b.x_mm - a.x_mm)
    };
    json(&PosesInFrame {
        timestamp: Time::at(ns),
        frame_id: ARENA_FRAME.into(),
        poses: path
            .iter()
            .enumerate()
            .map(|(i, &p)| pose(p, heading(i), 0.0))
            .collect(),
    })
}

/// Bearings one scan bin apart: the eight sensors' readings fall in the
/// bins of their bearings from the robot's centre.
const SCAN_BINS: usize = 72;

/// The proximity sensors as a scan in the robot's frame: each reading
/// within range at the distance it means from the robot's centre, in the
/// bin of its bearing; a bin with no reading holds 0 (its point lies at
/// the centre, under the body). Intensities are the raw readings.
pub(crate) fn scan(ns: u64, robot: &RobotModel, proximity: &[u16]) -> Value {
    let step = std::f64::consts::TAU / SCAN_BINS as f64;
    let mut ranges = vec![0.0; SCAN_BINS];
    let mut intensities = vec![0.0; SCAN_BINS];
    let floor = vl_core::ir_reading(robot.sensor_range_mm);
    for (mount, &reading) in robot.sensors.iter().zip(proximity) {
        let Some(d) = (f64::from(reading) > floor)
            .then(|| ir_distance(f64::from(reading)))
            .flatten()
        else {
            continue;
        };
        let (s, c) = mount.angle_rad.sin_cos();
        let (x, y) = (mount.x_mm + d * c, mount.y_mm + d * s);
        let bearing = y.atan2(x).rem_euclid(std::f64::consts::TAU);
        let bin = ((bearing / step).round() as usize) % SCAN_BINS;
        ranges[bin] = x.hypot(y) * MM;
        intensities[bin] = f64::from(reading);
    }
    json(&LaserScan {
        timestamp: Time::at(ns),
        frame_id: ROBOT_FRAME.into(),
        pose: pose(Point::default(), 0.0, 0.01),
        start_angle: 0.0,
        end_angle: step * (SCAN_BINS - 1) as f64,
        ranges,
        intensities,
    })
}

/// Foxglove's log levels: 1 debug … 5 fatal.
#[derive(Debug, Clone, Copy)]
pub enum Level {
    Info = 2,
    Warning = 3,
}

pub(crate) fn log_message(ns: u64, level: Level, text: &str) -> Value {
    json(&Log {
        timestamp: Time::at(ns),
        level: level as u8,
        message: text.into(),
        name: "vl host".into(),
        file: String::new(),
        line: 0,
    })
}

/// The most points of a path drawn over the image: a 933-point path
/// costs no more than a frame's worth of annotations.
const ANNOTATED_POINTS: usize = 120;

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
        Point2 {
            x: (x * 10.0).round() / 10.0,
            y: (y * 10.0).round() / 10.0,
        }
    };
    let stride = path.len().div_ceil(ANNOTATED_POINTS).max(1);
    let mut drawn: Vec<Point2> = path.iter().step_by(stride).map(|&p| pixel(p)).collect();
    if let Some(&last) = path.last()
        && !(path.len() - 1).is_multiple_of(stride)
    {
        drawn.push(pixel(last));
    }
    let points = (drawn.len() >= 2)
        .then(|| PointsAnnotation {
            timestamp: Time::at(ns),
            kind: 3,
            points: drawn,
            outline_color: rgba(0.1, 0.5, 1.0, 1.0),
            outline_colors: Vec::new(),
            fill_color: rgba(0.0, 0.0, 0.0, 0.0),
            thickness: 2.0,
        })
        .into_iter()
        .collect();
    let circles = robot
        .map(|(pose, radius_mm)| CircleAnnotation {
            timestamp: Time::at(ns),
            position: pixel(pose.point()),
            diameter: 2.0 * radius_mm / camera.mm_per_px(),
            thickness: 2.0,
            fill_color: rgba(0.0, 0.0, 0.0, 0.0),
            outline_color: rgba(1.0, 0.6, 0.0, 1.0),
        })
        .into_iter()
        .collect();
    json(&ImageAnnotations {
        circles,
        points,
        texts: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_heading_is_a_rotation_about_z() {
        let q = Quaternion::about_z(std::f64::consts::PI);
        assert!((q.z - 1.0).abs() < 1e-12);
        assert!(q.w.abs() < 1e-12);
    }

    #[test]
    fn a_long_path_is_drawn_over_the_image_in_a_few_points_ending_at_its_end() {
        let camera = CameraModel::overhead(800.0, 600.0, 640, 15.0);
        let path: Vec<Point> = (0..933)
            .map(|i| Point {
                x_mm: 50.0 + f64::from(i) * 0.7,
                y_mm: 300.0,
            })
            .collect();
        let drawn = annotations(5, &camera, &path, None);
        let points = drawn["points"][0]["points"].as_array().unwrap();
        assert!(points.len() <= ANNOTATED_POINTS + 1, "{}", points.len());
        let (x, _) = camera.to_pixel(path[932]);
        let last = points.last().unwrap()["x"].as_f64().unwrap();
        assert!((last - x).abs() < 0.1, "{last} {x}");
        assert!(serde_json::to_vec(&drawn).unwrap().len() < 8_000);
    }

    #[test]
    fn a_schema_is_written_out_whole_under_its_name() {
        let schema = Kind::SceneUpdate.schema();
        let text = schema.body.to_string();
        assert!(!text.contains("$ref"), "{text}");
        assert_eq!(schema.body["title"], "foxglove.SceneUpdate");
        let entity = &schema.body["properties"]["entities"]["items"];
        let required = entity["required"].as_array().unwrap();
        for field in ["arrows", "spheres", "triangles", "texts", "models"] {
            assert!(required.contains(&Value::from(field)), "{field}: {entity}");
        }
    }
}
