//! A deterministic simulator of the lab: the Khepera robot on its arena,
//! its proximity sensors and the overhead camera. Everything advances on a
//! virtual clock in fixed steps with a seeded random source, so the same
//! seed and inputs give the same run on any machine.
//!
//! Also here: the Khepera's serial protocol answered by the simulated
//! robot (and put on a pseudo-terminal), the Internet link as a model, and
//! scripted or path-following runs with a fingerprint of their trace.
//!
//! In detail:
//!
//! - modules: a deterministic simulator: the Khepera on its arena at a fixed
//!   10 ms step with a seeded generator — first-order speed response, wheel
//!   slip, contact (`world`), the IR response scaled by reflectivity
//!   (`proximity`), the overhead camera with optional lens offset, blur,
//!   noise, lighting gradient, tilt, barrel distortion, motion blur over the
//!   exposure, a cable across the marker, drawn by a `Renderer` that keeps
//!   the still scene between frames, and its calibration from a rendered dot
//!   target (`camera`), how far odometry drifts from the truth over UMBmark
//!   squares (`odometry`, `vl sim odometry`), people's doings on the virtual
//!   clock: a box put down, a hand over the robot (`scene`), the Khepera
//!   protocol answered by the simulated robot (`khepera`, over `vl-core`'s
//!   `KheperaCommand`) and put on a pseudo-terminal with a real line's timing
//!   at its baud, each command and reply taking its characters' time
//!   (`emulator`, `vl khepera-emu`), the Internet link as a netem-style model
//!   with named `Profile`s (`link`) and as a WebSocket's messages see it over
//!   TCP — in order, a loss as a retransmission's wait, a disconnect as a
//!   closed connection — with profiles from name or JSON file (`tcp`), runs
//!   scripted or following the path a Guest would plan, lasting as long as
//!   that path needs (`script`), and its real-time factor (`bench`)

mod bench;
mod camera;
mod emulator;
mod forecast;
mod khepera;
mod link;
mod noise;
mod odometry;
mod optics;
mod scene;
mod script;
mod tcp;
mod world;

pub use bench::{FORECAST_SEEDS, SimBench, SimBenchError, bench};
pub use camera::{Renderer, SimCalibration, calibrate, camera_for, render_target};
pub use emulator::{Emulator, EmulatorError, PortSettings};
pub use forecast::{
    CONTROLLER_S, Controllers, ForecastError, Forecasting, LONGEST_S, Pilot, forecast,
};
pub use khepera::Khepera;
pub use link::{
    Distribution, Expected, Link, LinkModel, LinkReport, LinkStats, Loss, Profile, measure,
};
pub use odometry::{OdometryFit, measure_odometry};
pub use optics::{Optics, OpticsError, OpticsPreset};
pub use scene::{SceneEvent, Scheduled};
pub use script::{Driver, RunReport, Tracking, WheelSchedule, WheelScheduleError, run};
pub use tcp::{Delivery, LinkSpecError, MessageLink, RTO_MS};
pub use world::{STEP_S, SimError, World};
