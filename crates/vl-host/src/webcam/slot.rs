//! The newest frame of a camera whose frames come on their own (a network
//! camera's stream read on a thread, a ROS 2 topic's subscription): kept as
//! they arrive, only the newest, so a Host that looks less often than the
//! camera sends never sees an old one; `grab` waits for one newer than the
//! last it took.

use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use vl_core::CameraModel;

use super::pixels::{PixelFormat, declared_size, decode};
use crate::drivers::{CameraError, Captured};

/// `grab` waits this long for a frame newer than the last.
const GRAB_WAIT: Duration = Duration::from_secs(1);

/// The newest frame, and what went wrong last.
#[derive(Default)]
pub struct Newest {
    pub jpeg: Option<(Vec<u8>, Instant)>,
    /// Frames kept so far: `grab` waits for this to pass what it had.
    pub count: u64,
    pub error: Option<String>,
    /// The camera's size once known: a frame declaring another is dropped
    /// as it arrives, never kept in place of the last good one.
    pub size: Option<(u32, u32)>,
}

/// Where the frames' reader and `grab` meet.
#[derive(Default)]
pub struct FrameSlot {
    newest: Mutex<Newest>,
    arrived: Condvar,
}

impl FrameSlot {
    pub fn lock(&self) -> MutexGuard<'_, Newest> {
        self.newest.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Tells whoever waits that the slot changed (a frame, an error).
    pub fn notify(&self) {
        self.arrived.notify_all();
    }

    /// Keeps `jpeg`, taken at `taken`, as the newest frame, unless it is
    /// not of the camera's size; whether it was kept.
    pub fn keep(&self, jpeg: Vec<u8>, taken: Instant) -> bool {
        {
            let mut newest = self.lock();
            if let Some(size) = newest.size
                && declared_size(&jpeg) != Some(size)
            {
                return false;
            }
            newest.jpeg = Some((jpeg, taken));
            newest.count += 1;
        }
        self.notify();
        true
    }

    /// Waits at most `wait` for what `ready` looks for in the slot.
    pub fn wait_for(
        &self,
        wait: Duration,
        ready: impl Fn(&Newest) -> bool,
    ) -> MutexGuard<'_, Newest> {
        let deadline = Instant::now() + wait;
        let mut newest = self.lock();
        while !ready(&newest) && Instant::now() < deadline {
            newest = self
                .arrived
                .wait_timeout(newest, deadline.saturating_duration_since(Instant::now()))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
        newest
    }

    /// The first frame newer than the `seen`th (which it becomes),
    /// waiting a second at most, decoded as a frame of camera `model`
    /// called `name`.
    pub fn grab(
        &self,
        seen: &mut u64,
        model: &CameraModel,
        name: &str,
    ) -> Result<Captured, CameraError> {
        let newest = self.wait_for(GRAB_WAIT, |n| n.count != *seen);
        let (jpeg, taken) = match (&newest.jpeg, newest.count != *seen) {
            (Some((jpeg, taken)), true) => (jpeg.clone(), *taken),
            _ => {
                let why = newest
                    .error
                    .clone()
                    .unwrap_or_else(|| "no new frame".into());
                return Err(CameraError::Silent(format!("{name}: {why}")));
            }
        };
        *seen = newest.count;
        drop(newest);
        let (w, h) = (model.width_px, model.height_px);
        let image = decode(PixelFormat::Mjpeg, &jpeg, w, h, 0).map_err(|e| e.within(name))?;
        Ok(Captured { image, taken })
    }
}
