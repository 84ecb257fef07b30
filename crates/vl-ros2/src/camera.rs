//! `--camera ros2:TOPIC` with `--robot ros2`: the lab's overhead camera is
//! a ROS 2 camera's JPEG stream (sensor_msgs/CompressedImage). The newest
//! frame is kept as it arrives, as a network camera's is; `grab` decodes
//! it by the webcams' own decoder (`webcam::FrameSlot`, as a network
//! camera's). Its size is the first frame's, and a frame of another size,
//! or not JPEG, is dropped as it arrives.

use std::sync::Arc;
use std::time::{Duration, Instant};

use vl_core::CameraModel;

use super::graph::{Node, Qos, TopicSubscription};
use super::messages::CompressedImage;
use vl_host::{Camera, CameraError, Captured, believed};
use vl_host::{FrameSlot, MAX_CAMERA_SIDE, declared_size};

/// How long opening waits for the first frame, which gives the size.
const FIRST_FRAME: Duration = Duration::from_secs(5);
/// Frames a second the camera is believed to send without a calibration.
const ASSUMED_FPS: f64 = 15.0;

/// Keeps `image` as the newest frame if it is a JPEG of a size a camera
/// may have (and, once known, of the camera's).
fn keep(slot: &FrameSlot, image: CompressedImage) {
    let fits = declared_size(&image.data)
        .is_some_and(|(w, h)| w <= MAX_CAMERA_SIDE && h <= MAX_CAMERA_SIDE);
    if fits && image.format.to_ascii_lowercase().contains("jpeg") {
        slot.keep(image.data, Instant::now());
    }
}

/// A ROS 2 camera topic as the lab's camera.
pub(crate) struct Ros2Camera {
    topic: String,
    model: CameraModel,
    slot: Arc<FrameSlot>,
    seen: u64,
    _subscription: TopicSubscription,
}

impl Ros2Camera {
    /// Subscribes to `topic` on `node` and waits for its first frame; the
    /// camera is seen through `calibration`, or as looking straight down
    /// on a `floor_mm` floor.
    pub(crate) async fn open(
        node: &Node,
        topic: &str,
        calibration: Option<CameraModel>,
        floor_mm: (f64, f64),
    ) -> Result<Ros2Camera, CameraError> {
        let slot = Arc::new(FrameSlot::default());
        if let Some(model) = calibration {
            slot.lock().size = Some((model.width_px, model.height_px));
        }
        let into = slot.clone();
        let subscription = node
            .subscribe(topic, Qos::SENSOR, move |image: CompressedImage, _| {
                keep(&into, image)
            })
            .await
            .map_err(|e| CameraError::Setup(format!("ROS 2 {topic}: {e}")))?;
        let waited = Instant::now();
        let size = loop {
            let first = (slot.lock().jpeg.as_ref()).and_then(|(jpeg, _)| declared_size(jpeg));
            if let Some(size) = first {
                break size;
            }
            if waited.elapsed() > FIRST_FRAME {
                return Err(CameraError::Silent(format!(
                    "no JPEG on ROS 2 {topic} within {} s",
                    FIRST_FRAME.as_secs()
                )));
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        };
        let model = calibration.unwrap_or_else(|| believed(None, floor_mm, size.0, ASSUMED_FPS));
        // From now on a frame of another size is dropped as it arrives.
        slot.lock().size = Some((model.width_px, model.height_px));
        Ok(Ros2Camera {
            topic: topic.to_owned(),
            model,
            slot,
            seen: 0,
            _subscription: subscription,
        })
    }
}

impl Camera for Ros2Camera {
    fn model(&self) -> CameraModel {
        self.model
    }

    fn grab(&mut self) -> Result<Captured, CameraError> {
        let name = format!("ROS 2 {}", self.topic);
        self.slot.grab(&mut self.seen, &self.model, &name)
    }
}
