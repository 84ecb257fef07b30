//! The camera as the lab's sensor (thesis B.1, B.3): the first frame maps
//! the floor, every frame locates the robot for the control loop, and the
//! frames the policy picks (appendix G) go to the Guests as JPEG.

use std::io::Cursor;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::SyncSender;
use std::thread;
use std::time::{Duration, Instant};
use vl_record::Feed;

use bytes::Bytes;
use image::RgbImage;
use image::codecs::jpeg::JpegEncoder;
use tokio::sync::watch;
use tracing::{debug, info, warn};
use vl_core::{
    Arena, CameraModel, DeviceState, FrameHeader, Grid, ImageFormat, Look, Pose, arena_of,
    changed_cells, look,
};

use super::{LabStatus, RETRY_MAX};
use crate::drivers::{Camera, Captured};

/// The robot where a frame showed it, and when the frame was taken.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sighting {
    pub taken: Instant,
    pub pose: Pose,
    /// Whether `taken` is when the frame was taken, not when it was seen:
    /// an undated sighting is behind the odometry by the camera's latency,
    /// so disagreeing with it proves nothing.
    pub dated: bool,
}

/// Sightings waiting for the control loop, at most: it takes them every
/// control period, far more often than frames come.
pub(crate) const SIGHTINGS: usize = 4;

/// The camera map's cell, mm: finer than the planner's, so the obstacles
/// the safety layer keeps the robot from are within a millimetre of where
/// they are (a VGA camera over the largest arena sees about 1.3 mm per px).
const MAP_CELL_MM: f64 = 2.0;

/// Which camera frames the Host sends (thesis appendix G).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FramePolicy {
    /// Every frame the camera takes: live video.
    EveryFrame,
    /// A frame when the scene changes beyond the robot (an obstacle placed
    /// or moved, a hand), when a client asks, and at least every
    /// `max_interval`; the robot is painted out of it, as Guests draw the
    /// robot from the pose in the feedback.
    OnChange { max_interval: Duration },
}

/// The cell of the grid frames are compared on, mm, and how many of its
/// cells must differ for the scene to have changed: a 20 mm object
/// anywhere on the floor, not the noise along an obstacle's edge.
const CHANGE_CELL_MM: f64 = 10.0;
const CHANGED_CELLS: usize = 4;
/// JPEG quality of the frames sent: a webcam's own.
const JPEG_QUALITY: u8 = 80;

/// How often the first frame is tried before the lab falls back on its model.
const FIRST_FRAME_TRIES: u32 = 5;

/// The floor as the camera first sees it, and where it sees the robot.
pub(crate) struct FirstLook {
    pub map: Arena,
    pub robot: Option<(Instant, Pose)>,
}

/// Maps the `floor` (the lab's arena, of which only the size, name and goal
/// are used) from a frame of `camera`: the lab's obstacles are what the
/// camera sees. Falls back on the model, saying why, when no frame comes
/// or the robot is not in it (its body would count as an obstacle).
pub(crate) fn first_look(camera: &mut dyn Camera, floor: &Arena) -> FirstLook {
    let model = camera.model();
    let fallback = |why: String| {
        warn!("{why}: the lab's map is the arena model until the camera sees it");
        FirstLook {
            map: floor.clone(),
            robot: None,
        }
    };
    let mut last_error = None;
    for _ in 0..FIRST_FRAME_TRIES {
        match camera.grab() {
            Ok(frame) => {
                return map_from(&frame.image, &model, floor, frame.taken).unwrap_or_else(fallback);
            }
            Err(e) => last_error = Some(e),
        }
        thread::sleep(Duration::from_millis(100));
    }
    fallback(format!(
        "no frame from the camera ({})",
        last_error.map_or_else(String::new, |e| e.to_string())
    ))
}

fn map_from(
    frame: &RgbImage,
    model: &CameraModel,
    floor: &Arena,
    taken: Instant,
) -> Result<FirstLook, String> {
    let seen = look(frame, model);
    let robot = seen
        .robot
        .ok_or_else(|| "the camera does not see the robot".to_string())?;
    let grid = seen
        .obstacles(model, floor.width_mm, floor.height_mm, MAP_CELL_MM)
        .map_err(|e| format!("cannot grid the floor: {e}"))?;
    let mut map = arena_of(&grid, &floor.name, Some(robot));
    map.goal = floor.goal;
    info!(
        obstacles = map.obstacles.len(),
        "mapped the floor from the camera"
    );
    Ok(FirstLook {
        map,
        robot: Some((taken, robot)),
    })
}

pub(crate) struct CameraLoop {
    pub camera: Box<dyn Camera>,
    pub frames: watch::Sender<Option<Bytes>>,
    pub sightings: SyncSender<Sighting>,
    pub event: Arc<AtomicU64>,
    pub since: Instant,
    pub running: Arc<AtomicBool>,
    pub status: Arc<watch::Sender<LabStatus>>,
    pub policy: FramePolicy,
    /// A client asked for a frame.
    pub wanted: Arc<AtomicBool>,
    /// How many clients watch.
    pub watchers: Arc<AtomicUsize>,
    /// The floor's size, mm, over which scenes are compared.
    pub floor_mm: (f64, f64),
    /// Fold each sighting in at its frame's exposure (else at its arrival,
    /// as a lab that ignores its camera's delay does: for comparison).
    pub compensate_latency: bool,
    /// The recorder, handed every frame sent while a run is recorded.
    pub record: Feed,
}

/// What the last frame sent showed, to tell whether the scene changed.
struct Sent {
    at: Instant,
    scene: Option<Grid>,
}

/// A frame taken, on its way to the Guests.
struct Taken {
    image: RgbImage,
    seen: Look,
    started: Instant,
    capture_us: u64,
    event: u64,
}

/// Picks, encodes and publishes the frames Guests get, on a thread of its
/// own at a lower priority: encoding for people must never hold up the
/// sightings the control loop steers by.
struct Publisher {
    frames: watch::Sender<Option<Bytes>>,
    watchers: Arc<AtomicUsize>,
    policy: FramePolicy,
    wanted: Arc<AtomicBool>,
    floor_mm: (f64, f64),
    model: CameraModel,
    record: Feed,
}

impl CameraLoop {
    /// Takes frames at the camera's rate and locates the robot in each, at
    /// the control loop's priority: a busy machine slows the video Guests
    /// see, not the sightings the robot is kept safe by.
    pub(crate) fn run(mut self) {
        let model = self.camera.model();
        let period = Duration::from_secs_f64(1.0 / model.fps.max(0.1));
        // One frame waits for the publisher at most; one it has not taken
        // yet is passed over for the newer.
        let (to_publish, taken) = std::sync::mpsc::sync_channel::<Taken>(1);
        let publisher = Publisher {
            frames: self.frames.clone(),
            watchers: self.watchers.clone(),
            policy: self.policy,
            wanted: self.wanted.clone(),
            floor_mm: self.floor_mm,
            model,
            record: self.record.clone(),
        };
        thread::Builder::new()
            .name("vl-frames".into())
            .spawn(move || publisher.run(taken))
            .expect("the OS starts a thread");
        while self.running.load(Ordering::Relaxed) {
            let started = Instant::now();
            let event = self.event.load(Ordering::Relaxed);
            match self.camera.grab() {
                Ok(Captured { image, taken }) => {
                    let capture_us = taken.saturating_duration_since(self.since).as_micros() as u64;
                    let seen = look(&image, &model);
                    if let Some(pose) = seen.robot {
                        // A full queue means the control loop is behind: this
                        // sighting would be stale by the time it is read.
                        let dated = self.compensate_latency;
                        let taken = if dated { taken } else { Instant::now() };
                        let _ = self.sightings.try_send(Sighting { taken, pose, dated });
                    }
                    let _ = to_publish.try_send(Taken {
                        image,
                        seen,
                        started,
                        capture_us,
                        event,
                    });
                }
                Err(e) => {
                    if self.status.borrow().camera == DeviceState::Online {
                        warn!("{e}; the camera is offline until it answers again");
                        self.status.send_modify(|s| s.camera = DeviceState::Offline);
                    }
                    thread::sleep(RETRY_MAX.min(period * 10));
                    continue;
                }
            }
            if self.status.borrow().camera == DeviceState::Offline {
                info!("the camera answers again");
                self.status.send_modify(|s| s.camera = DeviceState::Online);
            }
            thread::sleep(period.saturating_sub(started.elapsed()));
        }
    }
}

impl Publisher {
    fn run(self, taken: std::sync::mpsc::Receiver<Taken>) {
        crate::priority::yield_to_control(CAMERA_NICE, "camera");
        let mut seq = 0u64;
        let mut sent: Option<Sent> = None;
        // Ends when the camera loop does.
        while let Ok(Taken {
            mut image,
            seen,
            started,
            capture_us,
            event,
        }) = taken.recv()
        {
            if self.watchers.load(Ordering::Relaxed) == 0 {
                // Nobody to send to: keep no frame, which would be stale
                // when someone comes.
                if sent.take().is_some() {
                    self.frames.send_replace(None);
                }
                continue;
            }
            let Some(scene) = self.to_send(&seen, sent.as_ref()) else {
                continue;
            };
            if matches!(self.policy, FramePolicy::OnChange { .. }) {
                seen.erase_robot(&mut image);
            }
            match jpeg(&image) {
                Ok(bytes) => {
                    seq += 1;
                    let header = FrameHeader {
                        format: ImageFormat::Jpeg,
                        width: image.width() as u16,
                        height: image.height() as u16,
                        seq,
                        event,
                        capture_us,
                    };
                    let wire = Bytes::from(header.encode(&bytes));
                    self.record.frame(&wire);
                    self.frames.send_replace(Some(wire));
                    sent = Some(Sent { at: started, scene });
                }
                Err(e) => warn!("could not encode a camera frame: {e}"),
            }
        }
    }

    /// Whether the policy sends the frame `seen` was taken of: `Some` of
    /// the scene it shows (for the next comparison) if so.
    fn to_send(&self, seen: &Look, last: Option<&Sent>) -> Option<Option<Grid>> {
        let FramePolicy::OnChange { max_interval } = self.policy else {
            return Some(None);
        };
        let (w, h) = self.floor_mm;
        let scene = seen.obstacles(&self.model, w, h, CHANGE_CELL_MM).ok();
        let asked = self.wanted.swap(false, Ordering::Relaxed);
        let send = match last {
            None => true,
            Some(last) => {
                let changed = match (&scene, &last.scene) {
                    (Some(now), Some(then)) => changed_cells(now, then) >= CHANGED_CELLS,
                    _ => true,
                };
                if changed {
                    debug!("the scene changed: sending a frame");
                }
                asked || changed || last.at.elapsed() >= max_interval
            }
        };
        send.then_some(scene)
    }
}

/// A client watching the frames, counted while it lives.
pub struct Watching(Arc<AtomicUsize>);

impl Watching {
    pub fn new(watchers: &Arc<AtomicUsize>) -> Watching {
        watchers.fetch_add(1, Ordering::Relaxed);
        Watching(watchers.clone())
    }
}

impl Drop for Watching {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// How much less the frames' work counts than the Host's other threads,
/// in nice levels: choosing and encoding take milliseconds a frame, and
/// must not delay commands, pings, sightings or the control loop when the
/// machine is busy.
const CAMERA_NICE: i32 = 10;

/// `image` as JPEG, as webcams send it: a noisy frame is several times
/// smaller than as PNG.
fn jpeg(image: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    let mut bytes = Vec::new();
    JpegEncoder::new_with_quality(Cursor::new(&mut bytes), JPEG_QUALITY).encode_image(image)?;
    Ok(bytes)
}
