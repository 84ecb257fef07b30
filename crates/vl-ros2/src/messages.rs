//! The ROS 2 messages the lab speaks, as Rust types laid out in CDR field
//! by field as their vendored `.msg` files say (a property test walks
//! every encoding with the definitions to hold the two together). A Point
//! and a Vector3 share one type: the same three doubles.

use super::cdr::{CdrError, Reader, Writer};

/// A message of one ROS 2 type.
pub(crate) trait Message: Sized {
    /// Its full type name, `package/msg/Type`.
    const TYPE: &'static str;
    fn write(&self, w: &mut Writer);
    fn read(r: &mut Reader<'_>) -> Result<Self, CdrError>;

    fn encode(&self) -> Vec<u8> {
        let mut w = Writer::new();
        self.write(&mut w);
        w.finish()
    }

    fn decode(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut r = Reader::new(bytes)?;
        let message = Self::read(&mut r)?;
        r.end()?;
        Ok(message)
    }
}

/// builtin_interfaces/Time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Time {
    pub(crate) sec: i32,
    pub(crate) nanosec: u32,
}

impl Time {
    /// The wall clock now, which header stamps are.
    pub(crate) fn now() -> Time {
        let ns = vl_record::now_ns();
        Time {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    fn write(&self, w: &mut Writer) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }

    fn read(r: &mut Reader<'_>) -> Result<Time, CdrError> {
        Ok(Time {
            sec: r.i32("stamp")?,
            nanosec: r.u32("stamp")?,
        })
    }
}

/// std_msgs/Header.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Header {
    pub(crate) stamp: Time,
    pub(crate) frame_id: String,
}

impl Header {
    pub(crate) fn now(frame_id: &str) -> Header {
        Header {
            stamp: Time::now(),
            frame_id: frame_id.to_owned(),
        }
    }

    fn write(&self, w: &mut Writer) {
        self.stamp.write(w);
        w.string(&self.frame_id);
    }

    fn read(r: &mut Reader<'_>) -> Result<Header, CdrError> {
        Ok(Header {
            stamp: Time::read(r)?,
            frame_id: r.string("frame_id")?,
        })
    }
}

/// geometry_msgs/Vector3, and Point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Vector3 {
    pub(crate) x: f64,
    pub(crate) y: f64,
    pub(crate) z: f64,
}

impl Vector3 {
    fn write(&self, w: &mut Writer) {
        w.f64s(&[self.x, self.y, self.z]);
    }

    fn read(r: &mut Reader<'_>) -> Result<Vector3, CdrError> {
        let [x, y, z] = r.f64s("vector")?;
        Ok(Vector3 { x, y, z })
    }
}

/// geometry_msgs/Quaternion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Quaternion {
    pub(crate) x: f64,
    pub(crate) y: f64,
    pub(crate) z: f64,
    pub(crate) w: f64,
}

impl Default for Quaternion {
    fn default() -> Quaternion {
        Quaternion::about_z(0.0)
    }
}

impl Quaternion {
    /// A turn of `theta` radians about +z.
    pub(crate) fn about_z(theta: f64) -> Quaternion {
        let (s, c) = (theta / 2.0).sin_cos();
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }

    /// The heading about +z this rotation gives the x axis.
    pub(crate) fn yaw(&self) -> f64 {
        let (x, y, z, w) = (self.x, self.y, self.z, self.w);
        (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
    }

    fn write(&self, w: &mut Writer) {
        w.f64s(&[self.x, self.y, self.z, self.w]);
    }

    fn read(r: &mut Reader<'_>) -> Result<Quaternion, CdrError> {
        let [x, y, z, w] = r.f64s("quaternion")?;
        Ok(Quaternion { x, y, z, w })
    }
}

/// geometry_msgs/Pose.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Pose {
    pub(crate) position: Vector3,
    pub(crate) orientation: Quaternion,
}

impl Pose {
    fn write(&self, w: &mut Writer) {
        self.position.write(w);
        self.orientation.write(w);
    }

    fn read(r: &mut Reader<'_>) -> Result<Pose, CdrError> {
        Ok(Pose {
            position: Vector3::read(r)?,
            orientation: Quaternion::read(r)?,
        })
    }
}

/// geometry_msgs/Twist: m/s and rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Twist {
    pub(crate) linear: Vector3,
    pub(crate) angular: Vector3,
}

impl Message for Twist {
    const TYPE: &'static str = "geometry_msgs/msg/Twist";

    fn write(&self, w: &mut Writer) {
        self.linear.write(w);
        self.angular.write(w);
    }

    fn read(r: &mut Reader<'_>) -> Result<Twist, CdrError> {
        Ok(Twist {
            linear: Vector3::read(r)?,
            angular: Vector3::read(r)?,
        })
    }
}

/// nav_msgs/Odometry, its covariances row-major 6 × 6.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Odometry {
    pub(crate) header: Header,
    pub(crate) child_frame_id: String,
    pub(crate) pose: Pose,
    pub(crate) pose_covariance: [f64; 36],
    pub(crate) twist: Twist,
    pub(crate) twist_covariance: [f64; 36],
}

impl Message for Odometry {
    const TYPE: &'static str = "nav_msgs/msg/Odometry";

    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        w.string(&self.child_frame_id);
        self.pose.write(w);
        w.f64s(&self.pose_covariance);
        self.twist.write(w);
        w.f64s(&self.twist_covariance);
    }

    fn read(r: &mut Reader<'_>) -> Result<Odometry, CdrError> {
        Ok(Odometry {
            header: Header::read(r)?,
            child_frame_id: r.string("child_frame_id")?,
            pose: Pose::read(r)?,
            pose_covariance: r.f64s("covariance")?,
            twist: Twist::read(r)?,
            twist_covariance: r.f64s("covariance")?,
        })
    }
}

/// geometry_msgs/TransformStamped: where `child_frame_id` is in
/// `header.frame_id`.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct TransformStamped {
    pub(crate) header: Header,
    pub(crate) child_frame_id: String,
    pub(crate) translation: Vector3,
    pub(crate) rotation: Quaternion,
}

impl TransformStamped {
    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        w.string(&self.child_frame_id);
        self.translation.write(w);
        self.rotation.write(w);
    }

    fn read(r: &mut Reader<'_>) -> Result<TransformStamped, CdrError> {
        Ok(TransformStamped {
            header: Header::read(r)?,
            child_frame_id: r.string("child_frame_id")?,
            translation: Vector3::read(r)?,
            rotation: Quaternion::read(r)?,
        })
    }
}

/// tf2_msgs/TFMessage.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct TfMessage {
    pub(crate) transforms: Vec<TransformStamped>,
}

impl Message for TfMessage {
    const TYPE: &'static str = "tf2_msgs/msg/TFMessage";

    fn write(&self, w: &mut Writer) {
        w.count(self.transforms.len());
        for t in &self.transforms {
            t.write(w);
        }
    }

    fn read(r: &mut Reader<'_>) -> Result<TfMessage, CdrError> {
        // A transform is at least its header's 12 bytes and 7 doubles.
        let n = r.count(12 + 56, "transforms")?;
        let transforms = (0..n)
            .map(|_| TransformStamped::read(r))
            .collect::<Result<_, _>>()?;
        Ok(TfMessage { transforms })
    }
}

/// sensor_msgs/CompressedImage.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct CompressedImage {
    pub(crate) header: Header,
    /// `jpeg`.
    pub(crate) format: String,
    pub(crate) data: Vec<u8>,
}

impl Message for CompressedImage {
    const TYPE: &'static str = "sensor_msgs/msg/CompressedImage";

    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        w.string(&self.format);
        w.bytes(&self.data);
    }

    fn read(r: &mut Reader<'_>) -> Result<CompressedImage, CdrError> {
        Ok(CompressedImage {
            header: Header::read(r)?,
            format: r.string("format")?,
            data: r.bytes("data")?,
        })
    }
}

/// sensor_msgs/CameraInfo, the region of interest the whole image.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct CameraInfo {
    pub(crate) header: Header,
    pub(crate) height: u32,
    pub(crate) width: u32,
    pub(crate) distortion_model: String,
    pub(crate) d: Vec<f64>,
    pub(crate) k: [f64; 9],
    pub(crate) r: [f64; 9],
    pub(crate) p: [f64; 12],
}

impl Message for CameraInfo {
    const TYPE: &'static str = "sensor_msgs/msg/CameraInfo";

    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.distortion_model);
        w.count(self.d.len());
        w.f64s(&self.d);
        w.f64s(&self.k);
        w.f64s(&self.r);
        w.f64s(&self.p);
        // binning_x, binning_y, then the region of interest: none.
        for _ in 0..6 {
            w.u32(0);
        }
        w.bool(false);
    }

    fn read(r: &mut Reader<'_>) -> Result<CameraInfo, CdrError> {
        let info = CameraInfo {
            header: Header::read(r)?,
            height: r.u32("height")?,
            width: r.u32("width")?,
            distortion_model: r.string("distortion_model")?,
            d: r.f64_sequence("d")?,
            k: r.f64s("k")?,
            r: r.f64s("r")?,
            p: r.f64s("p")?,
        };
        for _ in 0..6 {
            r.u32("binning and roi")?;
        }
        r.bool("roi")?;
        Ok(info)
    }
}

/// sensor_msgs/LaserScan: angles in rad, ranges in m.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct LaserScan {
    pub(crate) header: Header,
    pub(crate) angle_min: f32,
    pub(crate) angle_max: f32,
    pub(crate) angle_increment: f32,
    pub(crate) time_increment: f32,
    pub(crate) scan_time: f32,
    pub(crate) range_min: f32,
    pub(crate) range_max: f32,
    pub(crate) ranges: Vec<f32>,
    pub(crate) intensities: Vec<f32>,
}

impl Message for LaserScan {
    const TYPE: &'static str = "sensor_msgs/msg/LaserScan";

    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        for v in [
            self.angle_min,
            self.angle_max,
            self.angle_increment,
            self.time_increment,
            self.scan_time,
            self.range_min,
            self.range_max,
        ] {
            w.f32(v);
        }
        w.f32_sequence(&self.ranges);
        w.f32_sequence(&self.intensities);
    }

    fn read(r: &mut Reader<'_>) -> Result<LaserScan, CdrError> {
        Ok(LaserScan {
            header: Header::read(r)?,
            angle_min: r.f32("angle_min")?,
            angle_max: r.f32("angle_max")?,
            angle_increment: r.f32("angle_increment")?,
            time_increment: r.f32("time_increment")?,
            scan_time: r.f32("scan_time")?,
            range_min: r.f32("range_min")?,
            range_max: r.f32("range_max")?,
            ranges: r.f32_sequence("ranges")?,
            intensities: r.f32_sequence("intensities")?,
        })
    }
}

/// nav_msgs/OccupancyGrid: row-major from the origin, 0 free, 100 taken,
/// −1 unknown.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct OccupancyGrid {
    pub(crate) header: Header,
    pub(crate) map_load_time: Time,
    /// m per cell.
    pub(crate) resolution: f32,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) origin: Pose,
    pub(crate) data: Vec<i8>,
}

impl Message for OccupancyGrid {
    const TYPE: &'static str = "nav_msgs/msg/OccupancyGrid";

    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        self.map_load_time.write(w);
        w.f32(self.resolution);
        w.u32(self.width);
        w.u32(self.height);
        self.origin.write(w);
        w.count(self.data.len());
        for &cell in &self.data {
            w.i8(cell);
        }
    }

    fn read(r: &mut Reader<'_>) -> Result<OccupancyGrid, CdrError> {
        let header = Header::read(r)?;
        let map_load_time = Time::read(r)?;
        let (resolution, width, height) = (r.f32("resolution")?, r.u32("width")?, r.u32("height")?);
        let origin = Pose::read(r)?;
        let n = r.count(1, "data")?;
        let data = (0..n).map(|_| r.i8("data")).collect::<Result<_, _>>()?;
        Ok(OccupancyGrid {
            header,
            map_load_time,
            resolution,
            width,
            height,
            origin,
            data,
        })
    }
}
