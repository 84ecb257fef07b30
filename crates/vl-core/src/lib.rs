//! What the vl Guest and Host share: the protocol they speak over the
//! Media, the robot and arena models, and algorithms both sides run.

pub mod arena;
pub mod camera;
pub mod experiment;
pub mod frame;
pub mod protocol;
pub mod robot;
pub mod session;
pub mod steer;
pub mod vision;
