//! A deterministic simulator of the lab: the Khepera robot on its arena,
//! its proximity sensors and the overhead camera. Everything advances on a
//! virtual clock in fixed steps with a seeded random source, so the same
//! seed and inputs give the same run on any machine.
//!
//! Also here: the Khepera's serial protocol answered by the simulated
//! robot (and put on a pseudo-terminal), the Internet link as a model, and
//! scripted or path-following runs with a fingerprint of their trace.

mod bench;
mod camera;
mod emulator;
mod khepera;
mod link;
mod noise;
mod odometry;
mod optics;
mod scene;
mod script;
mod tcp;
mod world;

pub use bench::{SimBench, bench};
pub use camera::{Renderer, SimCalibration, calibrate, camera_for, render_target};
pub use emulator::{Emulator, EmulatorError, Line};
pub use khepera::Khepera;
pub use link::{
    Distribution, Expected, Link, LinkModel, LinkReport, LinkStats, Loss, Profile, measure,
};
pub use odometry::{OdometryFit, measure_odometry};
pub use optics::{Optics, OpticsError};
pub use scene::{SceneEvent, Scheduled};
pub use script::{Driver, RunReport, Script, ScriptError, Tracking, run};
pub use tcp::{Delivery, LinkSpecError, MessageLink, RTO_MS};
pub use world::{STEP_S, SimError, World};
