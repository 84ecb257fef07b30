//! Which camera watches the arena, as `--camera` names it, and opening it.

use std::path::PathBuf;
use std::str::FromStr;

use vl_core::{Arena, CameraModel};

use crate::drivers::{Camera, CameraError};
use crate::footage::FootageCamera;
use crate::webcam::HttpCamera;

/// Frames per second footage and network cameras are taken at when no
/// calibration says otherwise.
const ASSUMED_FPS: f64 = 15.0;

/// Which camera watches the arena.
#[derive(Clone, PartialEq, Debug)]
pub enum CameraSource {
    /// The simulated overhead camera (watches the simulated robot only).
    Sim,
    /// No camera: Guests get feedback but no frames.
    None,
    /// Recorded footage: the images of a directory, played back in name order.
    Replay(PathBuf),
    /// A network camera streaming MJPEG over HTTP, at this URL.
    Http(String),
    /// A webcam on Video4Linux2.
    #[cfg(target_os = "linux")]
    V4l2(crate::V4l2Spec),
}

impl FromStr for CameraSource {
    type Err = CameraError;

    fn from_str(text: &str) -> Result<CameraSource, CameraError> {
        match text {
            "sim" => Ok(CameraSource::Sim),
            "none" => Ok(CameraSource::None),
            _ if text.starts_with("http://") => Ok(CameraSource::Http(text.to_owned())),
            #[cfg(target_os = "linux")]
            _ if text.starts_with("v4l2:") => text["v4l2:".len()..].parse().map(CameraSource::V4l2),
            _ => match text.strip_prefix("dir:") {
                Some(dir) if !dir.is_empty() => Ok(CameraSource::Replay(dir.into())),
                _ => Err(CameraError::Address(format!(
                    "'{text}' is no camera: use sim, none, http://… (an MJPEG stream), \
                     v4l2:/dev/videoN (a webcam), dir:PATH (recorded footage) or \
                     ros2:/TOPIC (a ROS 2 robot's camera)"
                ))),
            },
        }
    }
}

impl CameraSource {
    /// The real camera this names, seen through `calibration` or, without
    /// one, as looking straight down on the `arena`'s floor; none for the
    /// simulated camera or none at all.
    pub fn open(
        self,
        calibration: Option<CameraModel>,
        arena: &Arena,
    ) -> Result<Option<Box<dyn Camera>>, CameraError> {
        let floor = (arena.width_mm, arena.height_mm);
        Ok(Some(match self {
            CameraSource::Sim | CameraSource::None => return Ok(None),
            CameraSource::Replay(dir) => {
                Box::new(FootageCamera::open(&dir, calibration, floor, ASSUMED_FPS)?)
            }
            CameraSource::Http(url) => {
                Box::new(HttpCamera::open(&url, calibration, floor, ASSUMED_FPS)?)
            }
            #[cfg(target_os = "linux")]
            CameraSource::V4l2(spec) => {
                Box::new(crate::V4l2Camera::open(spec, calibration, floor)?)
            }
        }))
    }
}
