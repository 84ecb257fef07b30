//! The hardware the Host drives, behind small traits (as OpenRR's `arci`
//! does), so experiment control runs the same on a real robot and camera
//! as on the simulator.

use std::time::{Duration, Instant};

use image::RgbImage;
use thiserror::Error;
use vl_core::{CameraModel, Leash, Pose, Priority, RobotModel, WheelSpeeds};

/// A robot that cannot be reached, stopped answering or answered nonsense.
#[derive(Debug, Error)]
pub enum RobotError {
    #[error("cannot open the robot's line {device}: {reason}")]
    Open { device: String, reason: String },
    #[error("the robot did not answer {sent} within {waited_ms} ms")]
    Timeout { sent: String, waited_ms: u128 },
    #[error("the robot answered {sent} with '{got}'")]
    Garbled { sent: String, got: String },
    #[error("the robot's line failed: {0}")]
    Io(std::io::Error),
    /// What it reports contradicts what it reported before.
    #[error("the robot's odometry cannot be trusted: {0}")]
    Untrusted(String),
}

/// Why a camera gives no frame. Each says which camera, and why, in words.
#[derive(Debug, Error)]
pub enum CameraError {
    /// Its address names no camera `vl` reads.
    #[error("camera: {0}")]
    Address(String),
    /// It cannot be opened, or not set up as asked.
    #[error("camera: {0}")]
    Setup(String),
    /// It sent nothing in time, or stopped: it may come back.
    #[error("camera: {0}")]
    Silent(String),
    /// It sent a frame that is no image of the size it was set to.
    #[error("camera: {0}")]
    Frame(String),
}

impl CameraError {
    /// The same error, said of the camera named `camera`.
    pub(crate) fn within(self, camera: &str) -> CameraError {
        let named = |why: String| format!("{camera}: {why}");
        match self {
            CameraError::Address(why) => CameraError::Address(named(why)),
            CameraError::Setup(why) => CameraError::Setup(named(why)),
            CameraError::Silent(why) => CameraError::Silent(named(why)),
            CameraError::Frame(why) => CameraError::Frame(named(why)),
        }
    }
}

/// What one read of the robot tells.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotReading {
    /// Dead reckoning from the wheel encoders since the lab started: it
    /// drifts, and the camera corrects it.
    pub odometry: Pose,
    pub wheels: WheelSpeeds,
    pub proximity: Vec<u16>,
    /// Pressing against something.
    pub contact: bool,
    /// How far each wheel has turned, mm (its encoder count): what a
    /// leash's reach counts from.
    pub travel_mm: [f64; 2],
    /// When the odometry was sampled (at the latest): what the safety layer
    /// reckons the pose's age from.
    pub taken: Instant,
}

/// A differential-drive robot with proximity sensors.
pub trait Robot: Send {
    fn model(&self) -> &RobotModel;
    /// Drives by `leash`, its reach counted from the wheels' travel at the
    /// last `read`: the robot stops at its end by itself, whatever becomes
    /// of the Host. A stop leash stops the wheels at once.
    fn drive(&mut self, leash: &Leash) -> Result<(), RobotError>;
    fn read(&mut self) -> Result<RobotReading, RobotError>;
    /// Tries to reach the robot again after its link failed.
    fn reconnect(&mut self) -> Result<(), RobotError> {
        Ok(())
    }
    /// The priority of the process that holds the robot's line for the
    /// Host, if one does (the serial guard).
    fn guard_priority(&self) -> Option<Priority> {
        None
    }
    /// How long the last `drive` took to reach the wheels: on a serial
    /// line, its exchange at the line's baud.
    fn command_latency(&self) -> Duration {
        Duration::ZERO
    }
}

/// A frame and when it was taken. A real camera's frame arrives tens of
/// milliseconds after its exposure: the pose estimate folds the robot it
/// shows in at the moment of the exposure, not of the arrival.
pub struct Captured {
    pub image: RgbImage,
    pub taken: Instant,
}

/// An overhead camera.
pub trait Camera: Send {
    /// The camera as calibrated: how its pixels map to the floor.
    fn model(&self) -> CameraModel;
    /// The newest frame (waiting for it at most a few frame periods).
    fn grab(&mut self) -> Result<Captured, CameraError>;
}

/// How a real camera is believed to see the floor: as `calibration` says,
/// or without one as looking straight down on a `floor_mm` floor, across
/// its `width_px` columns, at `fps`.
pub fn believed(
    calibration: Option<CameraModel>,
    floor_mm: (f64, f64),
    width_px: u32,
    fps: f64,
) -> CameraModel {
    calibration.unwrap_or_else(|| CameraModel::overhead(floor_mm.0, floor_mm.1, width_px, fps))
}

/// Where the robot truly is, which only a simulator knows. The Host hands
/// it to nothing but a run's record, to measure afterwards how far the run
/// strayed: it never steers, guards or ends a run by it.
pub trait Witness: Send {
    fn true_pose(&mut self) -> Pose;
}
