//! What the vl Guest and Host share: the protocol they speak over the
//! Media, the robot and arena models, and algorithms both sides run.

pub mod arena;
pub mod camera;
pub mod cspace;
pub mod experiment;
pub mod follow;
pub mod frame;
pub mod nf1;
pub mod plan;
pub mod protocol;
pub mod robot;
pub mod session;
pub mod spline;
pub mod teleop;
pub mod vision;
