//! What a lab is built from — its robot, its camera, the arena, and for
//! the simulated lab its optics and seed — and which of those go together:
//! the simulated camera watches only the simulated robot, a real camera
//! only a real one.

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::pin::Pin;
use std::sync::Arc;

use vl_core::{Arena, CameraModel, RobotModel};
use vl_sim::{Optics, Scheduled};

use crate::drivers::{Camera, CameraError, Robot, RobotError};
use crate::khepera::KheperaSerial;
use crate::lab::Devices;
use crate::source::CameraSource;
use crate::{Host, HostConfig, HostError, SimCamera, SimLab};

/// Which robot the lab drives.
#[derive(Debug, Clone)]
pub enum RobotSpec {
    /// The simulated Khepera II.
    Sim,
    /// A Khepera on a serial line, held by a guard process (`guard`, the
    /// program run as `vl serial-guard`) that stops it if the Host dies.
    Khepera {
        port: String,
        baud: u32,
        guard: PathBuf,
    },
    /// A robot a plug-in connects (a ROS 2 base, `vl-ros2`), with the
    /// camera it brings, if any.
    Plugged(Arc<dyn RobotPlug>),
}

/// A robot, and the camera that came with it.
pub struct PluggedRobot {
    pub robot: Box<dyn Robot>,
    /// The robot's own camera (a topic on its network), if it brings one.
    pub camera: Option<Box<dyn Camera>>,
}

/// A robot driver that plugs into the lab from outside it, as the ROS 2
/// side does a ROS 2 base: the lab's drivers behind one call.
pub trait RobotPlug: Send + Sync + std::fmt::Debug {
    /// Connects the robot (`model`, starting at `arena`'s start pose) and
    /// its own camera, seen through `calibration` (or looking straight
    /// down on `arena`).
    fn connect<'a>(
        &'a self,
        model: RobotModel,
        calibration: Option<CameraModel>,
        arena: &'a Arena,
    ) -> Pin<Box<dyn Future<Output = Result<PluggedRobot, SetupError>> + Send + 'a>>;
}

/// A lab to serve.
#[derive(Debug, Clone)]
pub struct LabSpec {
    pub robot: RobotSpec,
    pub camera: CameraSource,
    /// Where the robot starts: the simulated robot stands there, a real
    /// one's dead reckoning begins there.
    pub arena: Arena,
    pub model: RobotModel,
    /// The camera's calibration (none: a real camera is believed to look
    /// straight down; the simulated one is calibrated from a dot target).
    pub calibration: Option<CameraModel>,
    /// The simulated camera's optics.
    pub optics: Optics,
    /// The simulator's seed.
    pub seed: u64,
    /// What people do in the simulated lab while it runs.
    pub scene: Vec<Scheduled>,
}

/// A lab that cannot be built so.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error(
        "recorded footage shows a recorded robot, not the simulated one: replay it with --robot khepera"
    )]
    FootageOfTheSimulator,
    #[error("a real camera watches a real robot, not the simulated one: use --robot khepera")]
    RealCameraOnTheSimulator,
    #[error("the simulated camera watches only the simulated robot; use --camera none")]
    SimulatedCameraOnARobot,
    #[error(
        "no camera to watch the arena with (given a calibration, the Host does not wait for its first frame): {0}"
    )]
    Camera(#[source] CameraError),
    /// Recorded footage that cannot be played.
    #[error("{0}")]
    Footage(#[source] CameraError),
    #[error("no Khepera to drive: {0}")]
    Robot(#[source] RobotError),
    /// A plugged robot that would not connect.
    #[error("{0}")]
    Plugged(#[source] Box<dyn std::error::Error + Send + Sync>),
    #[error("cannot start the Host: {0}")]
    Host(#[from] HostError),
}

impl SetupError {
    /// Whether the lab asked for is the user's to fix (not a device's).
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            SetupError::FootageOfTheSimulator
                | SetupError::RealCameraOnTheSimulator
                | SetupError::SimulatedCameraOnARobot
                | SetupError::Footage(_)
        )
    }
}

impl Host {
    /// Builds the lab `spec` describes and serves it on `listen`.
    pub async fn serve(
        listen: SocketAddr,
        spec: LabSpec,
        config: HostConfig,
    ) -> Result<Host, SetupError> {
        match (spec.robot, spec.camera) {
            (RobotSpec::Sim, CameraSource::Replay(_)) => Err(SetupError::FootageOfTheSimulator),
            (RobotSpec::Sim, camera @ (CameraSource::Sim | CameraSource::None)) => {
                let lab = SimLab {
                    arena: spec.arena,
                    robot: spec.model,
                    seed: spec.seed,
                    camera: (camera == CameraSource::Sim).then_some(SimCamera {
                        optics: spec.optics,
                        calibration: spec.calibration,
                    }),
                    scene: spec.scene,
                };
                Ok(Host::start_sim(listen, lab, config).await?)
            }
            (RobotSpec::Sim, _) => Err(SetupError::RealCameraOnTheSimulator),
            (RobotSpec::Khepera { .. } | RobotSpec::Plugged(_), CameraSource::Sim) => {
                Err(SetupError::SimulatedCameraOnARobot)
            }
            (RobotSpec::Plugged(plug), camera) => {
                let plugged = plug
                    .connect(spec.model, spec.calibration, &spec.arena)
                    .await?;
                let camera = match plugged.camera {
                    Some(own) => Some(own),
                    None => camera
                        .open(spec.calibration, &spec.arena)
                        .map_err(SetupError::Camera)?,
                };
                let devices = Devices {
                    robot: plugged.robot,
                    camera,
                    witness: None,
                };
                Ok(Host::start(listen, devices, spec.arena, config).await?)
            }
            (RobotSpec::Khepera { port, baud, guard }, camera) => {
                let footage = matches!(camera, CameraSource::Replay(_));
                let camera =
                    camera
                        .open(spec.calibration, &spec.arena)
                        .map_err(|e| match footage {
                            true => SetupError::Footage(e),
                            false => SetupError::Camera(e),
                        })?;
                let robot =
                    KheperaSerial::guarded(guard, &port, baud, spec.model, spec.arena.start)
                        .map_err(SetupError::Robot)?;
                let devices = Devices {
                    robot: Box::new(robot),
                    camera,
                    witness: None,
                };
                Ok(Host::start(listen, devices, spec.arena, config).await?)
            }
        }
    }
}
