//! The vl Host: the lab machine's side. It drives the robot and camera
//! (behind the traits in `drivers`: simulated in `sim`, a real Khepera on
//! a serial line in `khepera`, whose speed controller `characterise`
//! measures), runs the experiment control loop (`lab`) and serves Guests
//! over WebSocket (`server`).

mod characterise;
mod drivers;
mod khepera;
mod lab;
mod line;
mod server;
mod sim;

use std::net::SocketAddr;

use tokio::net::TcpListener;
use vl_core::{Arena, RobotModel};

pub use characterise::{CharacteriseError, characterise};
pub use drivers::{Camera, CameraError, Robot, RobotError, RobotReading};
pub use khepera::KheperaSerial;
pub use line::run_guard;
pub use server::HostConfig;

/// Why a Host could not start.
#[derive(Debug, thiserror::Error)]
pub enum HostError {
    #[error("cannot listen on {0}: {1}")]
    Bind(SocketAddr, std::io::Error),
    #[error(transparent)]
    Sim(#[from] vl_sim::SimError),
}

/// Camera frames per second on the simulated lab.
const SIM_FPS: f64 = 15.0;
/// Width of the simulated camera's image.
const SIM_CAMERA_WIDTH_PX: u32 = 320;

/// A simulated lab: the robot in its arena (starting at the arena's start
/// pose), the simulator's seed, and whether a camera watches.
#[derive(Debug, Clone)]
pub struct SimLab {
    pub arena: Arena,
    pub robot: RobotModel,
    pub seed: u64,
    pub camera: bool,
}

impl SimLab {
    /// A Khepera II in `arena`, watched by the camera, seed 1.
    pub fn new(arena: Arena) -> SimLab {
        SimLab {
            arena,
            robot: RobotModel::khepera_ii(),
            seed: 1,
            camera: true,
        }
    }
}

/// A Host, bound and serving its lab in the background.
pub struct Host {
    pub addr: SocketAddr,
    task: tokio::task::JoinHandle<()>,
}

impl Host {
    /// Binds `listen` and serves `robot` (and `camera`, if there is one) on `arena`.
    pub async fn start(
        listen: SocketAddr,
        robot: Box<dyn Robot>,
        camera: Option<Box<dyn Camera>>,
        arena: Arena,
        config: HostConfig,
    ) -> Result<Host, HostError> {
        let lab = lab::Lab::spawn(robot, camera, arena);
        let listener = TcpListener::bind(listen)
            .await
            .map_err(|e| HostError::Bind(listen, e))?;
        let addr = listener
            .local_addr()
            .map_err(|e| HostError::Bind(listen, e))?;
        let task = tokio::spawn(server::serve(listener, lab, config));
        Ok(Host { addr, task })
    }

    /// Binds `listen` and serves the simulated `lab`.
    pub async fn start_sim(
        listen: SocketAddr,
        lab: SimLab,
        config: HostConfig,
    ) -> Result<Host, HostError> {
        let (robot, camera) = sim::sim_lab(
            lab.arena.clone(),
            lab.robot,
            lab.seed,
            SIM_CAMERA_WIDTH_PX,
            SIM_FPS,
        )?;
        let camera = lab.camera.then(|| Box::new(camera) as Box<dyn Camera>);
        Host::start(listen, Box::new(robot), camera, lab.arena, config).await
    }

    /// The WebSocket URL Guests connect to.
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// Serves until the process ends.
    pub async fn wait(mut self) {
        let _ = (&mut self.task).await;
    }
}

impl Drop for Host {
    fn drop(&mut self) {
        self.task.abort();
    }
}
