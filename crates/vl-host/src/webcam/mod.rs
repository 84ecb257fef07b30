//! Real cameras: a network camera streaming MJPEG over HTTP (`http`), a
//! V4L2 webcam on Linux (`v4l2`), and the one decode both put their
//! buffers through (`pixels`). Each keeps only the newest frame, stamps it
//! with when it was taken, and, when its camera goes away, fails `grab`
//! until the camera is back: the lab shows it offline meanwhile.

mod http;
mod pixels;
mod slot;
#[cfg(target_os = "linux")]
mod v4l2;

pub use http::HttpCamera;
pub use pixels::{MAX_CAMERA_SIDE, declared_size};
pub use pixels::{PixelFormat, decode};
pub use slot::FrameSlot;
#[cfg(target_os = "linux")]
pub use v4l2::{DeviceInfo, V4l2Camera, V4l2Spec, Webcams, list_devices};
