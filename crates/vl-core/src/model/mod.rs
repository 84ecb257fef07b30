//! The lab's models: the robot (its geometry, limits, kinematics and
//! serial protocol), the arena it drives in and the camera that watches it.
//! The Host sends them to the Guest at mount; the simulator runs them.

pub(crate) mod arena;
pub(crate) mod camera;
pub(crate) mod homography;
pub(crate) mod khepera;
pub(crate) mod leash;
pub(crate) mod lens;
pub(crate) mod pinhole;
pub(crate) mod proximity;
pub(crate) mod response_fit;
pub(crate) mod robot;
