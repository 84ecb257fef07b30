//! The lab as ROS 2 messages: what the Host knows (feedback, the scene,
//! the camera's calibration, a frame) in ROS's units and frames (REP 103
//! and 105: metres, radians, `map` → `odom` → `base_link`, and the camera's
//! optical frame). The lab locates its robot absolutely by its camera, so
//! `odom` coincides with `map`: `map` → `odom` is the identity, and
//! `odom` → `base_link` the pose the lab acts on.

use vl_core::{ARENA_CELL_MM, Arena, Feedback, Grid, RobotModel, ir_distance};

use super::messages::{
    CameraInfo, CompressedImage, Header, LaserScan, OccupancyGrid, Odometry, Pose, Quaternion,
    TfMessage, Time, TransformStamped, Twist, Vector3,
};

/// The lab's frames: ROS's names, each after `NAME/` for a cell (several
/// cells on one ROS 2 network each have their own).
pub(crate) struct Frames {
    map: String,
    odom: String,
    base: String,
    camera: String,
}

impl Frames {
    pub(crate) fn of(cell: Option<&str>) -> Frames {
        let name = |frame: &str| match cell {
            Some(cell) => format!("{cell}/{frame}"),
            None => frame.to_owned(),
        };
        Frames {
            map: name("map"),
            odom: name("odom"),
            base: name("base_link"),
            camera: name("camera"),
        }
    }
}

const MM: f64 = 1e-3;

/// How sure the pose is: a camera sighting's few millimetres, as a
/// variance on x, y and heading (ROS's covariance diagonal).
const POSE_VARIANCE: [f64; 3] = [2.5e-5, 2.5e-5, 1e-3];

/// `/odom`: the pose and the wheels' motion.
pub(crate) fn odometry(frames: &Frames, feedback: &Feedback, robot: &RobotModel) -> Odometry {
    let mut pose_covariance = [0.0; 36];
    // x, y and the rotation about z; the robot stays on the floor.
    for (i, variance) in [
        (0, POSE_VARIANCE[0]),
        (7, POSE_VARIANCE[1]),
        (35, POSE_VARIANCE[2]),
    ] {
        pose_covariance[i] = variance;
    }
    Odometry {
        header: Header::now(&frames.odom),
        child_frame_id: frames.base.clone(),
        pose: pose_of(feedback),
        pose_covariance,
        twist: twist_of(feedback, robot),
        twist_covariance: [0.0; 36],
    }
}

fn pose_of(feedback: &Feedback) -> Pose {
    Pose {
        position: Vector3 {
            x: feedback.pose.x_mm * MM,
            y: feedback.pose.y_mm * MM,
            z: 0.0,
        },
        orientation: Quaternion::about_z(feedback.pose.theta_rad),
    }
}

/// The body's velocity in its own frame from the wheels' speeds.
fn twist_of(feedback: &Feedback, robot: &RobotModel) -> Twist {
    let wheels = feedback.wheels;
    let turn = if robot.wheel_base_mm > 0.0 {
        (wheels.right_mm_s - wheels.left_mm_s) / robot.wheel_base_mm
    } else {
        0.0
    };
    Twist {
        linear: Vector3 {
            x: wheels.forward_mm_s() * MM,
            ..Vector3::default()
        },
        angular: Vector3 {
            z: turn,
            ..Vector3::default()
        },
    }
}

/// `/tf`: `odom` → `base_link` as `/odom` says, `map` → `odom`, and where
/// the camera is in `map`.
pub(crate) fn transforms(
    frames: &Frames,
    feedback: &Feedback,
    camera: &vl_core::Pinhole,
) -> TfMessage {
    let stamp = Time::now();
    let stamped = |parent: &str, child: &str, translation, rotation| TransformStamped {
        header: Header {
            stamp,
            frame_id: parent.into(),
        },
        child_frame_id: child.into(),
        translation,
        rotation,
    };
    let pose = pose_of(feedback);
    let [x, y, z] = camera.position_mm;
    let q = camera.orientation;
    TfMessage {
        transforms: vec![
            stamped(
                &frames.map,
                &frames.odom,
                Vector3::default(),
                Quaternion::default(),
            ),
            stamped(&frames.odom, &frames.base, pose.position, pose.orientation),
            stamped(
                &frames.map,
                &frames.camera,
                Vector3 {
                    x: x * MM,
                    y: y * MM,
                    z: z * MM,
                },
                Quaternion {
                    x: q.i,
                    y: q.j,
                    z: q.k,
                    w: q.w,
                },
            ),
        ],
    }
}

/// `/camera/camera_info`: the calibration as a pinhole with OpenCV's
/// plumb-bob lens.
pub(crate) fn camera_info(frames: &Frames, camera: &vl_core::Pinhole) -> CameraInfo {
    CameraInfo {
        header: Header::now(&frames.camera),
        height: camera.height_px,
        width: camera.width_px,
        distortion_model: "plumb_bob".into(),
        d: camera.plumb_bob.to_vec(),
        k: camera.k(),
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: camera.p(),
    }
}

/// `/camera/image_raw/compressed`: a JPEG as the camera sent it.
pub(crate) fn image(frames: &Frames, jpeg: &[u8]) -> CompressedImage {
    CompressedImage {
        header: Header::now(&frames.camera),
        format: "jpeg".into(),
        data: jpeg.to_vec(),
    }
}

/// Bins of `/scan` a turn: one a degree.
const SCAN_BINS: usize = 360;

/// `/scan`: the proximity sensors as a scan from `base_link`, one bin a
/// degree; a sensor's bin holds how far its obstacle is from the robot's
/// centre (the sensor sits on the rim looking out), every other bin
/// +inf (nothing seen).
pub(crate) fn scan(frames: &Frames, feedback: &Feedback, robot: &RobotModel) -> LaserScan {
    let increment = std::f64::consts::TAU / SCAN_BINS as f64;
    let mut ranges = vec![f32::INFINITY; SCAN_BINS];
    for (mount, &reading) in robot.sensors.iter().zip(&feedback.proximity) {
        let Some(distance) = ir_distance(f64::from(reading)) else {
            continue;
        };
        if distance > robot.sensor_range_mm {
            continue;
        }
        let angle = vl_core::wrap_angle(mount.angle_rad) + std::f64::consts::PI;
        let bin = ((angle / increment).round() as usize) % SCAN_BINS;
        let from_centre = mount.x_mm.hypot(mount.y_mm) + distance;
        ranges[bin] = ranges[bin].min((from_centre * MM) as f32);
    }
    LaserScan {
        header: Header::now(&frames.base),
        angle_min: -std::f32::consts::PI,
        angle_max: (std::f64::consts::PI - increment) as f32,
        angle_increment: increment as f32,
        time_increment: 0.0,
        scan_time: 0.0,
        range_min: (robot.radius_mm * MM) as f32,
        range_max: ((robot.radius_mm + robot.sensor_range_mm) * MM) as f32,
        ranges,
        intensities: Vec::new(),
    }
}

/// `/map`: the floor as the camera mapped it, 0 free and 100 taken, rows
/// from the floor's y = 0 up, in `map`. The arena's walls, its edge, are
/// taken: a ROS 2 planner keeps off them as the lab's own does.
pub(crate) fn map(frames: &Frames, arena: &Arena) -> Option<OccupancyGrid> {
    let grid = Grid::from_arena(arena, ARENA_CELL_MM).ok()?;
    let (width, height) = (grid.width as usize, grid.height as usize);
    // `Grid` keeps its top row first; ROS's rows go along +y.
    let data = grid
        .blocked
        .chunks(width)
        .rev()
        .enumerate()
        .flat_map(|(y, row)| {
            row.iter().enumerate().map(move |(x, &blocked)| {
                let wall = x == 0 || y == 0 || x + 1 == width || y + 1 == height;
                if blocked || wall { 100 } else { 0 }
            })
        })
        .collect();
    let now = Time::now();
    Some(OccupancyGrid {
        header: Header {
            stamp: now,
            frame_id: frames.map.clone(),
        },
        map_load_time: now,
        resolution: (grid.cell_mm * MM) as f32,
        width: grid.width,
        height: grid.height,
        origin: Pose::default(),
        data,
    })
}
