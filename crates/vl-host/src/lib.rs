//! The vl Host: the lab machine's side. It drives the robot and camera
//! (behind the traits in `drivers`: simulated in `sim`, a real Khepera on
//! a serial line in `khepera`, recorded footage played back in `footage`,
//! real cameras over HTTP or V4L2 in `webcam`; the Khepera's speed
//! controller `characterise` measures), which camera `--camera` names
//! (`source`) and which robot and camera go together (`setup`), runs the
//! experiment control loop (`lab`) and serves Guests over WebSocket
//! (`server`), letting in whom its accounts and token say (`accounts`:
//! Argon2id accounts, the gate every hello passes with its delays and
//! limits on failures, the audit log; and whom an extension's sessions
//! vouch for, as an LMS's launches do in `vl-lti`); and the Media, a relay that puts a
//! modelled Internet link between Guests and a Host (`media`). Every run
//! is recorded as an MCAP file Foxglove opens, through `vl-record`.
//!
//! In detail:
//!
//! - modules: the lab machine: hardware behind small traits (`drivers`:
//!   `Robot`, which reports odometry, never a true pose; `Camera`, which
//!   reports its calibration; `Witness`, the simulator's truth, for a run's
//!   record only; typed `RobotError`), their simulated implementations
//!   (`sim`: the camera exposes frames on a thread of its own, which arrive
//!   the optics' delay later, some never) beside real cameras — an MJPEG
//!   stream over HTTP read on a thread that keeps the newest frame and
//!   reconnects, a V4L2 webcam through `linuxvideo`, both through one decode
//!   of MJPEG (standard Huffman tables put back) and YUYV (`webcam`) — and
//!   the real Khepera on a serial line with dead-reckoning odometry
//!   (`khepera`) held through a guard process that stops the robot when the
//!   Host dies or freezes (`line`; hidden `vl serial-guard`), its speed
//!   controller's characterisation (`characterise`; `vl khepera
//!   characterise`), the real-time loops (`lab/`): the camera loop maps the
//!   floor from the first frame and locates the robot in every frame at an
//!   ordinary priority, while a niced thread picks (by its
//!   `FramePolicy`), encodes and sends frames to Guests, newest only, and
//!   nothing while no welcomed client watches (`camera`); the control loop
//!   fuses sightings and odometry, acts on a command as it arrives (at most
//!   every 2 ms) and otherwise every 10 ms, follows a defined path or the
//!   operator, applies the watchdog, assistance, then the safety layer (its
//!   margin widened by the estimate's uncertainty) before every wheel
//!   command, ends a followed run that comes no further for 5 s saying where
//!   and why (`held_back`), turns in place to a heading at a run's goal when
//!   asked, and records the run's paths (`control`); the WebSocket server
//!   (`server/`): who gets a connection, at most 256 (`MAX_CONNECTIONS`) of
//!   which 128 (`MAX_UNWELCOMED`) not yet welcomed and 64
//!   (`MAX_UNWELCOMED_PER_ADDRESS`) of those from one address, a newcomer pushing out the
//!   oldest silent one of its own address, or else of the address holding the
//!   most, bare sockets before upgraded ones — idle sockets from one machine
//!   only push out each other (`admission`, which the Media uses too); one
//!   task per connection with the handshake, hello, ping and write timeouts,
//!   size and rate limits and a bounded outbox (`connection`); the hub, sole
//!   owner of session state, which asks the supervisor before every action,
//!   gives the map's C-space and teleoperation field (made once, when the
//!   Host starts) on mount and builds each definition's field with its
//!   virtual obstacles off the hub, on one blocking thread, the newest
//!   definition waiting in place of older ones, tells every client each
//!   change of the net's marking, takes the emergency stop from anyone, ends
//!   the run of an operator whose lease runs out, holds the role and the run
//!   (robot still) for an operator whose link dropped until the grace ends,
//!   keeps the line for control, first come first served, and ends an
//!   operator's slot by handing control to the next (`hub::queue`),
//!   makes the lab ready after a run (not after an emergency stop, a fault, a
//!   lost robot or a run held back) by planning a route back to the start
//!   pose off the hub and driving it as a run of its own, refusing Start
//!   meanwhile, says who pressed an emergency stop, and counts each run's
//!   synchronisation from the commands' `seen` (`hub`); the operator-latency
//!   benchmark, `vl host bench` (`bench`); the Media, a relay that holds each
//!   message for the delay a `MessageLink` gives it, closes a Guest's
//!   connection with the reason when its Host does not answer, closes and
//!   refuses connections during a scheduled disconnect, keeps for a client
//!   that does not read only the newest 2 MiB of frames, records each leg's
//!   delays and measures its own cost (`media`)
//! - velocities paced into commands (`server::pacing`, for Foxglove and
//!   ROS 2); the one handle every part reaches the lab by (`LabHandle`,
//!   the hub's client messages in `hub`); what plugs into the lab
//!   (`server::extension`: its pages on the lab's port, the sessions it
//!   opens for the gate, its part of the status, a task given the lab's
//!   handle, hearing its events, `server::events`), as a gateway's cell
//!   (`vl-cells`), the lab on ROS 2 (`vl-ros2`) and the LMS side
//!   (`vl-lti`) do; a robot driver from outside (`setup::RobotPlug`, as a
//!   ROS 2 base is); every secret the lab hands out (`secret`)

mod accounts;
mod characterise;
mod drivers;
#[cfg(test)]
mod dummy;
mod footage;
mod hush;
mod khepera;
mod lab;
mod line;
mod media;
mod memory;
mod priority;
mod reach;
mod secret;
mod server;
mod setup;
mod sim;
mod source;
mod tls;
mod webcam;

use std::net::SocketAddr;

use tokio::net::TcpListener;
use vl_core::{Arena, CalibrationError, CameraModel, RobotModel};
use vl_sim::{Optics, Scheduled};

pub use accounts::audit::{Audit, AuditEntry};
pub use accounts::gate::{
    ACCOUNT_ENDED, Admitted, Credentials, FAILURE_DELAY, FAILURE_REFILL, FAILURES_BURST, Gate,
    Identity, Observers, Purpose, Refusal, SessionCheck, SessionId,
};
pub use accounts::users::{AccountRole, Member, Roster, Users, UsersError};
pub use accounts::write_private;
pub use characterise::{CharacteriseError, characterise};
pub use drivers::{
    Camera, CameraError, Captured, Robot, RobotError, RobotReading, Witness, believed,
};
pub use footage::FootageCamera;
pub use hush::Hush;
pub use khepera::KheperaSerial;
pub use lab::{Devices, FramePolicy, Watching};
pub use line::run_guard;
pub use media::{
    Delays, Media, MediaBench, MediaBenchError, MediaConfig, MediaError, RelayRoundTrip,
    Reproduced, bench as media_bench,
};
pub use priority::raise_for_control as raise_priority;
pub use secret::secret;
pub use server::admission::Ticket;
pub use server::bench::{
    AgainstQuiet, BenchError, GatewayBench, GatewayCost, Guessing, OperatorLatency, WatchersBench,
    WatchersCost, operator_latency,
};
pub use server::bucket::Bucket;
pub use server::events::{LabEvent, LabEvents, LiveEvent, LiveEvents, RunDriver, RunEnded};
pub use server::extension::{
    Extension, ExtensionTask, SocketClient, SocketProtocol, run_all as run_extensions,
};
pub use server::origin::{AllowedOrigins, NotAnOrigin};
pub use server::pacing::Pacer;
pub use server::{
    Admission, ForecastSettings, HUB_QUEUE, HostConfig, LabHandle, MOST_FORECAST_SEEDS, accept,
    gate_of, watch_accounts,
};
pub use server::{socket, web};
pub use setup::{LabSpec, PluggedRobot, RobotPlug, RobotSpec, SetupError};
pub use source::CameraSource;
pub use tls::{Tls, TlsError};
#[cfg(target_os = "linux")]
pub use webcam::{DeviceInfo, V4l2Camera, V4l2Spec, Webcams, list_devices};
pub use webcam::{
    FrameSlot, HttpCamera, MAX_CAMERA_SIDE, PixelFormat, declared_size, decode as decode_pixels,
};

/// What a client of the hub (a connection, a cell's link, ROS 2's
/// operator) says to it and hears from it.
pub mod hub {
    pub use crate::server::hub::{OUTBOX, Status, Streams, ToConnection, ToHub};
}

/// Why a Host could not start.
#[derive(Debug, thiserror::Error)]
pub enum HostError {
    #[error("cannot listen on {0}: {1}")]
    Bind(SocketAddr, std::io::Error),
    #[error(transparent)]
    Sim(#[from] vl_sim::SimError),
    #[error("cannot calibrate the simulated camera: {0}")]
    Calibration(#[from] CalibrationError),
}

/// Camera frames per second on the simulated lab.
const SIM_FPS: f64 = 15.0;
/// Width of the simulated camera's image: a VGA webcam's.
const SIM_CAMERA_WIDTH_PX: u32 = 640;

/// A simulated lab: the robot in its arena (starting at the arena's start
/// pose), the simulator's seed, and the camera that watches, if any.
#[derive(Debug, Clone)]
pub struct SimLab {
    pub arena: Arena,
    pub robot: RobotModel,
    pub seed: u64,
    pub camera: Option<SimCamera>,
    /// What people do in the lab while it runs.
    pub scene: Vec<Scheduled>,
}

/// The simulated camera: how its optics spoil the ideal overhead view, and
/// the calibration the lab believes (none: the lab calibrates the camera
/// itself from a dot target on the floor, as lab staff do when it is set up).
#[derive(Debug, Clone, Default)]
pub struct SimCamera {
    pub optics: Optics,
    pub calibration: Option<CameraModel>,
}

impl SimLab {
    /// A Khepera II in `arena`, watched by an ideal camera, seed 1.
    pub fn new(arena: Arena) -> SimLab {
        SimLab {
            arena,
            robot: RobotModel::khepera_ii(),
            seed: 1,
            camera: Some(SimCamera::default()),
            scene: Vec::new(),
        }
    }
}

/// A Host, bound and serving its lab in the background.
pub struct Host {
    pub addr: SocketAddr,
    /// The certificate's fingerprint, when the Host speaks TLS.
    pin: Option<vl_core::Fingerprint>,
    /// What the processor gives the control loop and the serial guard.
    pub priority: vl_core::Priorities,
    task: tokio::task::JoinHandle<()>,
}

impl Host {
    /// Binds `listen` and serves `robot` (and `camera`, if there is one) on `arena`.
    pub async fn start(
        listen: SocketAddr,
        devices: Devices,
        arena: Arena,
        config: HostConfig,
    ) -> Result<Host, HostError> {
        let lab = lab::Lab::spawn(
            devices,
            arena,
            config.frames,
            config.compensate_latency,
            config.recordings.clone(),
        );
        let (listener, addr) = bind(listen).await?;
        let pin = config.tls.as_ref().map(|tls| tls.fingerprint);
        let priority = lab.priorities();
        let task = tokio::spawn(server::serve(listener, lab, config));
        Ok(Host {
            addr,
            pin,
            priority,
            task,
        })
    }

    /// Binds `listen` and serves the simulated `lab`.
    pub async fn start_sim(
        listen: SocketAddr,
        lab: SimLab,
        config: HostConfig,
    ) -> Result<Host, HostError> {
        let (width_mm, height_mm) = (lab.arena.width_mm, lab.arena.height_mm);
        let nominal = CameraModel::overhead(width_mm, height_mm, SIM_CAMERA_WIDTH_PX, SIM_FPS);
        let camera = lab.camera.clone().unwrap_or_default();
        let ideal = Optics {
            seed: camera.optics.seed,
            ..Optics::default()
        };
        let believed = match camera.calibration {
            Some(model) => model,
            None if camera.optics == ideal => nominal,
            None => {
                vl_sim::calibrate(&nominal, &camera.optics, width_mm, height_mm)?
                    .calibration
                    .camera
            }
        };
        let setup = sim::SimCameraSetup {
            nominal,
            optics: camera.optics,
            believed,
        };
        let (robot, sim_camera, witness) =
            sim::sim_lab(lab.arena.clone(), lab.robot, lab.seed, setup, lab.scene)?;
        let devices = Devices {
            robot: Box::new(robot),
            camera: lab
                .camera
                .is_some()
                .then(|| Box::new(sim_camera) as Box<dyn Camera>),
            witness: Some(Box::new(witness)),
        };
        Host::start(listen, devices, lab.arena, config).await
    }

    /// Where Guests connect: `ws://`, or with TLS `wss://` with the
    /// certificate's fingerprint for the Guest to pin.
    pub fn url(&self) -> String {
        self.url_at(self.addr)
    }

    /// Where a browser opens the web Guest (the same port).
    pub fn page_url(&self) -> String {
        self.page_url_at(self.addr)
    }

    /// Where Guests on other machines connect, and where their browsers
    /// open the page: one pair per address of this machine when the Host
    /// listens on every interface.
    pub fn reachable_at(&self) -> Vec<(String, String)> {
        reach::reachable(self.addr)
            .into_iter()
            .map(|at| (self.url_at(at), self.page_url_at(at)))
            .collect()
    }

    fn url_at(&self, at: SocketAddr) -> String {
        match self.pin {
            Some(pin) => format!("wss://{at}/#pin={pin}"),
            None => format!("ws://{at}"),
        }
    }

    fn page_url_at(&self, at: SocketAddr) -> String {
        let scheme = if self.pin.is_some() { "https" } else { "http" };
        format!("{scheme}://{at}/")
    }

    /// Serves until the process ends.
    pub async fn wait(mut self) {
        self.stopped().await;
    }

    /// Until the server stops by itself.
    pub async fn stopped(&mut self) {
        let _ = (&mut self.task).await;
    }

    /// Stops serving: the lab (and so the robot) stops, and the clients
    /// are told the Host is going (Foxglove's with close code 1001), given
    /// a moment to hear it.
    pub async fn stop(mut self) {
        self.task.abort();
        let _ = (&mut self.task).await;
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    }
}

/// Binds `listen`: the listener and the address it took (port 0 picks one).
pub async fn bind(listen: SocketAddr) -> Result<(TcpListener, SocketAddr), HostError> {
    let listener = TcpListener::bind(listen)
        .await
        .map_err(|e| HostError::Bind(listen, e))?;
    let addr = listener
        .local_addr()
        .map_err(|e| HostError::Bind(listen, e))?;
    Ok((listener, addr))
}

impl Drop for Host {
    fn drop(&mut self) {
        self.task.abort();
    }
}
