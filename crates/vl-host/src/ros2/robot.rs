//! `--robot ros2`: any ROS 2 differential-drive robot as the lab's robot,
//! behind the same safety layer, forecasts, recordings and Guests as a
//! Khepera. The lab publishes each wheel command as a Twist on `/cmd_vel`
//! and reads the robot's `/odom`. A ROS 2 base stops by itself when its
//! Twists stop (its controller's command timeout, 0.5 s in ROS 2's
//! diff_drive_controller): that bounds each motion on the robot's side, as
//! the leash does on a Khepera. The robot has no proximity sensors here:
//! the lab's map and its safety margins keep it off obstacles.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vl_core::{Leash, Pose, RobotModel, WheelSpeeds};

use super::Ros2Error;
use super::graph::{Node, Publisher, Qos, Subscription};
use super::messages::{Odometry, Twist, Vector3};
use crate::cells::ZenohOptions;
use crate::drivers::{Robot, RobotError, RobotReading};

/// An `/odom` older than this means the robot is gone.
const ODOM_SILENT: Duration = Duration::from_secs(1);
/// How long the lab waits for the robot's first `/odom`.
const FIRST_ODOM: Duration = Duration::from_secs(10);

/// Where the robot is on ROS 2.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2RobotOptions {
    pub domain: u32,
    pub zenoh: ZenohOptions,
}

/// The newest `/odom` and when it came.
type Latest = Arc<Mutex<Option<(Odometry, Instant)>>>;

/// A ROS 2 robot driven over Zenoh.
pub struct Ros2Robot {
    model: RobotModel,
    cmd_vel: Publisher<Twist>,
    latest: Latest,
    /// Each wheel's travel, mm, summed from the odometry's motion.
    travel_mm: [f64; 2],
    last_pose: Option<Pose>,
    _odom: Subscription,
    node: Node,
}

impl Ros2Robot {
    /// Joins the robot's Zenoh network and waits for its first `/odom`.
    pub async fn connect(
        options: &Ros2RobotOptions,
        model: RobotModel,
    ) -> Result<Ros2Robot, Ros2Error> {
        let node = super::node(&options.zenoh, options.domain, None, "vl_robot").await?;
        let latest: Latest = Arc::default();
        let into = latest.clone();
        let odom = node
            .subscribe("/odom", Qos::STATE, move |odometry: Odometry| {
                let mut latest = into.lock().unwrap_or_else(|e| e.into_inner());
                *latest = Some((odometry, Instant::now()));
            })
            .await?;
        let cmd_vel = node.publisher("/cmd_vel", Qos::STATE).await?;
        let waited = Instant::now();
        while latest.lock().unwrap_or_else(|e| e.into_inner()).is_none() {
            if waited.elapsed() > FIRST_ODOM {
                return Err(Ros2Error::NoRobot(FIRST_ODOM));
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        Ok(Ros2Robot {
            model,
            cmd_vel,
            latest,
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
    ) -> Result<super::camera::Ros2Camera, crate::drivers::CameraError> {
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
        let latest = self
            .latest
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let Some((odometry, taken)) = latest.filter(|(_, at)| at.elapsed() <= ODOM_SILENT) else {
            return Err(RobotError::Timeout {
                sent: "nothing (/odom is read)".into(),
                waited_ms: ODOM_SILENT.as_millis(),
            });
        };
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
