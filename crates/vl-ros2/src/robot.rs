//! `--robot ros2`: any ROS 2 differential-drive robot as the lab's robot,
//! behind the same safety layer, forecasts, recordings and Guests as a
//! Khepera. The lab publishes each wheel command as a Twist on `/cmd_vel`
//! and reads the robot's `/odom`. A ROS 2 base stops by itself when its
//! Twists stop (its controller's command timeout, 0.5 s in ROS 2's
//! diff_drive_controller): that bounds each motion on the robot's side, as
//! the leash does on a Khepera. The robot has no proximity sensors here:
//! the lab's map and its safety margins keep it off obstacles.
//!
//! `/odom` is the robot's only (`Odometer`): the lab takes the samples of
//! the one publisher it met at start (its attachment's GID), each
//! numbered after the last and within what the robot can do since;
//! another's samples are dropped, and a sample that contradicts the
//! robot's own history (a number not after the last: someone writing as
//! the robot; a leap faster than it goes) makes the robot untrusted for a
//! second: the lab stops driving it and its run ends. Odometry the camera
//! keeps contradicting ends the run too (the lab's, for any robot).

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tracing::warn;

use vl_core::{Leash, Pose, RobotModel, WheelSpeeds};

use super::Ros2Error;
use super::graph::{Node, Origin, Publisher, Qos, TopicSubscription};
use super::messages::{Odometry, Twist, Vector3};
use vl_cells::ZenohOptions;
use vl_host::{PluggedRobot, Robot, RobotError, RobotPlug, RobotReading, SetupError};

/// An `/odom` older than this means the robot is gone.
const ODOM_SILENT: Duration = Duration::from_secs(1);
/// How long the lab waits for the robot's first `/odom`.
const FIRST_ODOM: Duration = Duration::from_secs(10);
/// How long the lab listens to `/odom` at start for a second source.
const LISTEN_AT_START: Duration = Duration::from_millis(500);
/// A robot whose odometry contradicted itself is not driven for this long.
const UNTRUSTED_FOR: Duration = Duration::from_secs(1);
/// A sample may show the robot this much further than its top speed
/// carries it (jitter, a sample's own rounding), and this much more turned.
const LEAP_MM: f64 = 30.0;
const LEAP_RAD: f64 = 0.3;

/// Where the robot is on ROS 2.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2RobotOptions {
    pub domain: u32,
    pub zenoh: ZenohOptions,
    /// The robot's camera's JPEGs on this topic (`--camera ros2:/TOPIC`),
    /// if the lab watches the arena through it.
    pub camera: Option<String>,
}

impl RobotPlug for Ros2RobotOptions {
    fn connect<'a>(
        &'a self,
        model: RobotModel,
        calibration: Option<vl_core::CameraModel>,
        arena: &'a vl_core::Arena,
    ) -> Pin<Box<dyn Future<Output = Result<PluggedRobot, SetupError>> + Send + 'a>> {
        Box::pin(async move {
            let robot = Ros2Robot::connect(self, model)
                .await
                .map_err(|e| SetupError::Plugged(Box::new(e)))?;
            let camera = match &self.camera {
                Some(topic) => Some(Box::new(
                    robot
                        .camera(topic, calibration, arena)
                        .await
                        .map_err(SetupError::Camera)?,
                ) as Box<dyn vl_host::Camera>),
                None => None,
            };
            Ok(PluggedRobot {
                robot: Box::new(robot),
                camera,
            })
        })
    }
}

/// Which `/odom` samples are the robot's, and the newest of them.
pub(crate) struct Odometer {
    /// The robot's publisher, by the GID of the first sample met.
    robot: Option<Vec<u8>>,
    /// Every GID that spoke on `/odom`, to tell a second source at start.
    heard: Vec<Vec<u8>>,
    /// The robot's newest sample, its number and when it came.
    newest: Option<(Odometry, i64, Instant)>,
    /// When the odometry last contradicted itself, and how.
    untrusted: Option<(Instant, String)>,
    /// The most the robot moves and turns a second.
    top_mm_s: f64,
    top_rad_s: f64,
    hush: vl_host::Hush,
}

impl Odometer {
    pub(crate) fn new(model: &RobotModel) -> Odometer {
        let top_mm_s = model.max_wheel_speed_mm_s.abs();
        Odometer {
            robot: None,
            heard: Vec::new(),
            newest: None,
            untrusted: None,
            top_mm_s,
            top_rad_s: 2.0 * top_mm_s / model.wheel_base_mm.max(1.0),
            hush: vl_host::Hush::default(),
        }
    }

    /// Takes one sample of `/odom`, come at `now`.
    pub(crate) fn take(&mut self, odometry: Odometry, origin: Option<Origin>, now: Instant) {
        let Some(origin) = origin else {
            return self.ignore("a sample without rmw_zenoh's attachment");
        };
        if !self.heard.contains(&origin.gid) && self.heard.len() < 8 {
            self.heard.push(origin.gid.clone());
        }
        let robot = self.robot.get_or_insert_with(|| origin.gid.clone());
        if *robot != origin.gid {
            return self.ignore("a sample of another publisher than the robot's");
        }
        let contradiction = self.newest.as_ref().and_then(|(last, number, at)| {
            self.contradiction(last, *number, *at, &odometry, &origin, now)
        });
        // Numbered from here on even when contradicted: once only one
        // writes, its samples hold again.
        self.newest = Some((odometry, origin.sequence, now));
        if let Some(why) = contradiction {
            self.contradicted(now, why);
        }
    }

    /// How a sample contradicts the robot's last: a number not after its
    /// number, or a leap beyond what the robot can do in the time between.
    fn contradiction(
        &self,
        last: &Odometry,
        number: i64,
        at: Instant,
        odometry: &Odometry,
        origin: &Origin,
        now: Instant,
    ) -> Option<String> {
        if origin.sequence <= number {
            return Some(format!(
                "sample {} came after {number}: someone else writes as the robot",
                origin.sequence
            ));
        }
        let seconds = now.saturating_duration_since(at).as_secs_f64();
        let (from, to) = (pose_of(last), pose_of(odometry));
        let moved = (to.x_mm - from.x_mm).hypot(to.y_mm - from.y_mm);
        let turned = vl_core::wrap_angle(to.theta_rad - from.theta_rad).abs();
        (moved > 2.0 * self.top_mm_s * seconds + LEAP_MM
            || turned > 2.0 * self.top_rad_s * seconds + LEAP_RAD)
            .then(|| {
                format!(
                    "it leapt {moved:.0} mm and {turned:.2} rad in {:.0} ms, faster than it goes",
                    seconds * 1e3
                )
            })
    }

    fn ignore(&self, what: &str) {
        if self.hush.speak() {
            warn!("ROS 2 /odom: {what}, ignored");
        }
    }

    fn contradicted(&mut self, now: Instant, why: String) {
        if self.hush.speak() {
            warn!("ROS 2 /odom contradicts the robot's own: {why}");
        }
        self.untrusted = Some((now, why));
    }

    /// The robot's newest odometry and when it came, if it is to be
    /// trusted now.
    pub(crate) fn now(&self, now: Instant) -> Result<(Odometry, Instant), RobotError> {
        if let Some((at, why)) = &self.untrusted
            && now.saturating_duration_since(*at) < UNTRUSTED_FOR
        {
            return Err(RobotError::Untrusted(why.clone()));
        }
        match &self.newest {
            Some((odometry, _, at)) if now.saturating_duration_since(*at) <= ODOM_SILENT => {
                Ok((odometry.clone(), *at))
            }
            _ => Err(RobotError::Timeout {
                sent: "nothing (/odom is read)".into(),
                waited_ms: ODOM_SILENT.as_millis(),
            }),
        }
    }
}

type Shared = Arc<Mutex<Odometer>>;

fn locked(odometer: &Shared) -> std::sync::MutexGuard<'_, Odometer> {
    odometer.lock().unwrap_or_else(|e| e.into_inner())
}

/// A ROS 2 robot driven over Zenoh.
pub struct Ros2Robot {
    model: RobotModel,
    cmd_vel: Publisher<Twist>,
    odometer: Shared,
    /// Each wheel's travel, mm, summed from the odometry's motion.
    travel_mm: [f64; 2],
    last_pose: Option<Pose>,
    _odom: TopicSubscription,
    node: Node,
}

impl Ros2Robot {
    /// Joins the robot's Zenoh network and waits for its first `/odom`.
    pub async fn connect(
        options: &Ros2RobotOptions,
        model: RobotModel,
    ) -> Result<Ros2Robot, Ros2Error> {
        let node = super::node(&options.zenoh, options.domain, None, "vl_robot").await?;
        let odometer: Shared = Arc::new(Mutex::new(Odometer::new(&model)));
        let into = odometer.clone();
        let odom = node
            .subscribe("/odom", Qos::STATE, move |odometry: Odometry, origin| {
                locked(&into).take(odometry, origin, Instant::now());
            })
            .await?;
        let cmd_vel = node.publisher("/cmd_vel", Qos::STATE).await?;
        let waited = Instant::now();
        while locked(&odometer).newest.is_none() {
            if waited.elapsed() > FIRST_ODOM {
                return Err(Ros2Error::NoRobot(FIRST_ODOM));
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        // One robot: a second source on /odom from the start is refused.
        tokio::time::sleep(LISTEN_AT_START).await;
        let sources = locked(&odometer).heard.len();
        if sources > 1 {
            return Err(Ros2Error::Robot(format!(
                "{sources} publishers on /odom: the lab drives one robot, and cannot tell which"
            )));
        }
        Ok(Ros2Robot {
            model,
            cmd_vel,
            odometer,
            travel_mm: [0.0; 2],
            last_pose: None,
            _odom: odom,
            node,
        })
    }

    /// The robot's camera on `topic`, on the robot's own network: seen
    /// through `calibration`, or as looking straight down on `arena`.
    pub(crate) async fn camera(
        &self,
        topic: &str,
        calibration: Option<vl_core::CameraModel>,
        arena: &vl_core::Arena,
    ) -> Result<super::camera::Ros2Camera, vl_host::CameraError> {
        let floor = (arena.width_mm, arena.height_mm);
        super::camera::Ros2Camera::open(&self.node, topic, calibration, floor).await
    }
}

/// An odometry's pose in the lab's units.
fn pose_of(odometry: &Odometry) -> Pose {
    Pose {
        x_mm: odometry.pose.position.x * 1e3,
        y_mm: odometry.pose.position.y * 1e3,
        theta_rad: odometry.pose.orientation.yaw(),
    }
}

impl Robot for Ros2Robot {
    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn drive(&mut self, leash: &Leash) -> Result<(), RobotError> {
        let wheels = leash.wheels(&self.model);
        let base = self.model.wheel_base_mm.max(1.0);
        let twist = Twist {
            linear: Vector3 {
                x: wheels.forward_mm_s() * 1e-3,
                ..Vector3::default()
            },
            angular: Vector3 {
                z: (wheels.right_mm_s - wheels.left_mm_s) / base,
                ..Vector3::default()
            },
        };
        self.cmd_vel
            .put_wait(&twist)
            .map_err(|e| RobotError::Io(std::io::Error::other(format!("/cmd_vel: {e}"))))
    }

    fn read(&mut self) -> Result<RobotReading, RobotError> {
        let (odometry, taken) = locked(&self.odometer).now(Instant::now())?;
        let pose = pose_of(&odometry);
        // The wheels' travel from the body's motion since the last read.
        if let Some(last) = self.last_pose {
            let along = (pose.x_mm - last.x_mm).hypot(pose.y_mm - last.y_mm);
            let heading = vl_core::wrap_angle(pose.theta_rad - last.theta_rad);
            let forward = (pose.x_mm - last.x_mm) * last.theta_rad.cos()
                + (pose.y_mm - last.y_mm) * last.theta_rad.sin();
            let signed = along.copysign(forward);
            let turn = heading * self.model.wheel_base_mm / 2.0;
            self.travel_mm[0] += signed - turn;
            self.travel_mm[1] += signed + turn;
        }
        self.last_pose = Some(pose);
        let (v, w) = (odometry.twist.linear.x * 1e3, odometry.twist.angular.z);
        let half = w * self.model.wheel_base_mm / 2.0;
        Ok(RobotReading {
            odometry: pose,
            wheels: WheelSpeeds {
                left_mm_s: v - half,
                right_mm_s: v + half,
            },
            // No proximity sensors: nothing seen by any.
            proximity: vec![0; self.model.sensors.len()],
            contact: false,
            travel_mm: self.travel_mm,
            taken,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::messages::{Header, Pose as RosPose};
    use super::*;
    use proptest::prelude::*;

    fn at(x_mm: f64) -> Odometry {
        let mut pose = RosPose::default();
        pose.position.x = x_mm * 1e-3;
        Odometry {
            header: Header::default(),
            child_frame_id: "base_link".into(),
            pose,
            pose_covariance: [0.0; 36],
            twist: Twist::default(),
            twist_covariance: [0.0; 36],
        }
    }

    fn from(gid: u8, sequence: i64) -> Option<Origin> {
        Some(Origin {
            gid: vec![gid; 16],
            sequence,
        })
    }

    /// The robot moving 10 mm every 20 ms, sample `n`.
    fn robot(odometer: &mut Odometer, start: Instant, n: i64) {
        let now = start + Duration::from_millis(20 * n as u64);
        odometer.take(at(10.0 * n as f64), from(1, n), now);
    }

    #[test]
    fn a_stranger_s_samples_are_not_the_robot_s() {
        let mut odometer = Odometer::new(&RobotModel::khepera_ii());
        let start = Instant::now();
        for n in 1..=20 {
            robot(&mut odometer, start, n);
            // Standing at the start, as a publisher of its own; and with no attachment.
            odometer.take(
                at(0.0),
                from(2, n),
                start + Duration::from_millis(20 * n as u64),
            );
            odometer.take(at(0.0), None, start + Duration::from_millis(20 * n as u64));
        }
        let now = start + Duration::from_millis(400);
        let (odometry, _) = odometer.now(now).unwrap();
        assert!((pose_of(&odometry).x_mm - 200.0).abs() < 1e-9);
    }

    #[test]
    fn a_stranger_writing_as_the_robot_is_caught_and_then_forgotten() {
        let mut odometer = Odometer::new(&RobotModel::khepera_ii());
        let start = Instant::now();
        for n in 1..=10 {
            robot(&mut odometer, start, n);
        }
        // Its GID, numbers ahead of its own, the start pose.
        odometer.take(at(0.0), from(1, 1000), start + Duration::from_millis(205));
        robot(&mut odometer, start, 11);
        let now = start + Duration::from_millis(230);
        assert!(matches!(odometer.now(now), Err(RobotError::Untrusted(_))));
        // The robot alone again: trusted a second after the last contradiction.
        for n in 12..=70 {
            robot(&mut odometer, start, n);
        }
        let later = start + Duration::from_millis(1400);
        assert!(odometer.now(later).is_ok());
    }

    proptest! {
        /// A leap further than the robot can go in the time is a
        /// contradiction; anything it can do is not.
        #[test]
        fn leaps_beyond_the_robot_are_contradictions(ms in 1u64..200, share in 0.0f64..3.0) {
            let model = RobotModel::khepera_ii();
            let mut odometer = Odometer::new(&model);
            let start = Instant::now();
            odometer.take(at(0.0), from(1, 1), start);
            let seconds = ms as f64 / 1e3;
            let bound = 2.0 * model.max_wheel_speed_mm_s * seconds + LEAP_MM;
            let moved = bound * share;
            let now = start + Duration::from_millis(ms);
            odometer.take(at(moved), from(1, 2), now);
            let trusted = odometer.now(now).is_ok();
            prop_assert_eq!(trusted, moved <= bound);
        }
    }
}
