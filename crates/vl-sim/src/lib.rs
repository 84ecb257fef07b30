//! A deterministic simulator of the lab: the Khepera robot on its arena,
//! its proximity sensors and the overhead camera. Everything advances on a
//! virtual clock in fixed steps with a seeded random source, so the same
//! seed and inputs give the same run on any machine.

mod camera;
mod emulator;
mod khepera;
pub mod link;
mod noise;
mod proximity;
pub mod script;
mod world;

pub use camera::{Optics, camera_for};
pub use emulator::{Emulator, EmulatorError, Line};
pub use khepera::Khepera;
pub use proximity::proximity_value;
pub use world::{STEP_S, SimError, World};
