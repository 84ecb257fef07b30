//! Experiment control and sensed-data processing: the real-time loops that
//! turn commands into wheel speeds and robot and camera readings into
//! feedback and frames.
//!
//! Each loop runs on its own thread so a slow serial line or camera never
//! stalls the network side. They publish through `watch` channels, which keep
//! only the newest value: a slow client gets the latest feedback and frame,
//! never a queue of stale ones.

mod camera;
mod control;
mod controller;
mod run;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use bytes::Bytes;
use tokio::sync::{mpsc as async_mpsc, watch};
use vl_core::{
    Arena, CameraModel, Definition, DeviceState, Drive, EndReason, HostMessage, MapField,
    Priorities, Readiness, RobotModel, Summary,
};

use crate::drivers::{Camera, Robot, Witness};
pub use camera::FramePolicy;
pub use camera::Watching;
use camera::{CameraLoop, SIGHTINGS, first_look};
pub(crate) use control::map_field;
use control::{Control, Wiring};
pub(crate) use run::Conduct;
use vl_record::{Catalogue, Feed};

/// The control period: the Khepera's speed-controller period.
const TICK: Duration = Duration::from_millis(10);
/// Width of the arena drawing a Guest gets when the lab has no camera.
const NO_CAMERA_WIDTH_PX: u32 = 640;

/// How long the first retry of a lost robot or camera waits; each next
/// waits twice as long, up to `RETRY_MAX`: a device back from a pause is
/// found within about a second.
const RETRY_FIRST: Duration = Duration::from_millis(100);
const RETRY_MAX: Duration = Duration::from_secs(1);

/// Whether the lab's devices answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct LabStatus {
    pub robot: DeviceState,
    pub camera: DeviceState,
    /// What the processor gives the control loop and the serial guard.
    pub priority: Priorities,
}

impl LabStatus {
    /// The status message, with whether the lab is `ready` for a run.
    pub(crate) fn message(
        &self,
        lab: Readiness,
        last_run: Option<vl_core::RunRecord>,
    ) -> HostMessage {
        HostMessage::Status {
            robot: self.robot,
            camera: self.camera,
            lab,
            last_run,
        }
    }
}

/// Retries with back-off, and says so once per change of state.
struct Retry {
    next: Instant,
    wait: Duration,
}

impl Retry {
    fn new() -> Retry {
        Retry {
            next: Instant::now() + RETRY_FIRST,
            wait: RETRY_FIRST,
        }
    }

    /// Whether it is time for the next try; each try doubles the wait.
    fn due(&mut self) -> bool {
        if Instant::now() < self.next {
            return false;
        }
        self.wait = (self.wait * 2).min(RETRY_MAX);
        self.next = Instant::now() + self.wait;
        true
    }
}

/// The lab's devices: a robot, and perhaps a camera and (in simulation)
/// a witness of the truth.
pub struct Devices {
    pub robot: Box<dyn Robot>,
    pub camera: Option<Box<dyn Camera>>,
    pub witness: Option<Box<dyn Witness>>,
}

/// What the lab is, as the Guest needs it at mount.
#[derive(Debug, Clone)]
pub(crate) struct LabInfo {
    /// The map: the floor as the camera saw it when the lab started (the
    /// arena model when the lab has no camera).
    pub arena: Arena,
    pub robot: RobotModel,
    pub camera: CameraModel,
}

/// Requests from the session to the control loop.
#[derive(Debug)]
pub(crate) enum LabRequest {
    /// A run of `experiment` begins. Teleoperation adds the potential
    /// fields to the operator's commands and feeds the push back as a
    /// force; navigation ends when the robot reaches the goal.
    Start {
        /// The run's number, which its `Finished` carries back.
        run: u64,
        definition: Box<Definition>,
        conduct: Conduct,
        /// The map's potential field for assisted teleoperation.
        field: Option<Arc<MapField>>,
        /// At the goal, turn in place to face this heading, rad, before
        /// the run ends (the drive back to the start pose).
        face: Option<f64>,
        /// The user's controller, which drives the run.
        controller: Option<Arc<vl_sandbox::Module>>,
    },
    Drive {
        event: u64,
        drive: Drive,
    },
    /// Hold the running robot still (true) while its operator's link is
    /// down, or let the run go on (false) once they are back.
    Hold(bool),
    Finish(EndReason),
}

/// Run number `.0` ended; the session reports it.
#[derive(Debug, Clone)]
pub(crate) struct Finished(pub u64, pub Summary);

/// Lines of the Host's log a live watcher may fall behind by.
const LOG_LINES: usize = 64;
/// The recorder gives way to the control loop and the network side as
/// the camera's encoder does.
const RECORDER_NICE: i32 = 10;

/// The session's handle on the running lab.
pub(crate) struct Lab {
    pub info: LabInfo,
    requests: mpsc::Sender<LabRequest>,
    /// Newest robot feedback.
    pub feedback: watch::Receiver<Option<HostMessage>>,
    /// Newest camera frame, encoded for the wire…
    pub frames: watch::Receiver<Option<Bytes>>,
    /// …while anyone watches (welcomed clients): nobody watching, no frame
    /// is encoded.
    pub(crate) watchers: Arc<AtomicUsize>,
    /// Runs that ended.
    pub finished: async_mpsc::UnboundedReceiver<Finished>,
    /// Whether the robot and the camera answer.
    pub status: watch::Receiver<LabStatus>,
    running: Arc<AtomicBool>,
    frame_wanted: Arc<AtomicBool>,
    /// The recorder (none when the Host records nothing).
    pub(crate) record: Feed,
    /// ns since 1970 at the lab's clock's zero (feedback's `t_ms`, frames'
    /// capture times).
    pub(crate) since_ns: u64,
    /// The Host's log as it is written (firings, refusals, faults), for
    /// those watching it live; a watcher that falls behind skips lines.
    pub(crate) log: tokio::sync::broadcast::Sender<(vl_record::Level, String)>,
}

/// What the lab is, from the camera's first frame (the floor's map and
/// where the robot stands), or with no camera from the arena model.
fn look(
    arena: Arena,
    robot: &dyn Robot,
    camera: Option<&mut Box<dyn Camera>>,
) -> (LabInfo, Option<(Instant, vl_core::Pose)>) {
    let (map, seen, model) = match camera {
        Some(camera) => {
            let first = first_look(camera.as_mut(), &arena);
            (first.map, first.robot, camera.model())
        }
        None => {
            let model =
                CameraModel::overhead(arena.width_mm, arena.height_mm, NO_CAMERA_WIDTH_PX, 0.0);
            (arena, None, model)
        }
    };
    let info = LabInfo {
        arena: map,
        robot: robot.model().clone(),
        camera: model,
    };
    (info, seen)
}

impl Lab {
    /// Starts the control and camera loops on their own threads. With a
    /// camera, its first frame maps the floor of `arena` and locates the
    /// robot; without one, the arena model is the map and odometry alone
    /// says where the robot is. With a `catalogue`, runs are recorded there.
    pub(crate) fn spawn(
        devices: Devices,
        arena: Arena,
        policy: FramePolicy,
        compensate_latency: bool,
        catalogue: Option<Catalogue>,
    ) -> Lab {
        let since = Instant::now();
        let record = catalogue.map_or_else(Feed::default, |c| {
            Feed::spawn(c, since, || {
                crate::priority::yield_to_control(RECORDER_NICE, "recorder");
            })
        });
        let Devices {
            robot,
            mut camera,
            witness,
        } = devices;
        let floor_mm = (arena.width_mm, arena.height_mm);
        let (info, seen) = look(arena, robot.as_ref(), camera.as_mut());
        let (requests, request_rx) = mpsc::channel();
        let (sightings_tx, sightings) = mpsc::sync_channel(SIGHTINGS);
        let (feedback_tx, feedback) = watch::channel(None);
        let (frames_tx, frames) = watch::channel(None);
        let (finished_tx, finished) = async_mpsc::unbounded_channel();
        let (status_tx, status) = watch::channel(LabStatus {
            robot: DeviceState::Online,
            camera: if camera.is_some() {
                DeviceState::Online
            } else {
                DeviceState::Absent
            },
            priority: Priorities::default(),
        });
        let status_tx = Arc::new(status_tx);
        let running = Arc::new(AtomicBool::new(true));
        let frame_wanted = Arc::new(AtomicBool::new(false));
        let watchers = Arc::new(AtomicUsize::new(0));
        let event = Arc::new(AtomicU64::new(0));
        let wiring = Wiring {
            requests: request_rx,
            sightings: camera.is_some().then_some(sightings),
            feedback: feedback_tx,
            finished: finished_tx,
            event: event.clone(),
            status: status_tx.clone(),
            since,
            record: record.clone(),
        };
        let control = Control::new(robot, witness, info.clone(), seen, wiring);
        let (raised, priority) = mpsc::channel();
        thread::Builder::new()
            .name("vl-control".into())
            .spawn(move || {
                let priority = control.raise();
                let _ = raised.send(priority);
                control.run();
            })
            .expect("the OS starts a thread");
        // The thread asks first thing: its answer is here at once.
        let priority = priority.recv().unwrap_or_default();
        status_tx.send_modify(|s| s.priority = priority);
        if let Some(camera) = camera {
            let camera_loop = CameraLoop {
                camera,
                frames: frames_tx,
                sightings: sightings_tx,
                event,
                since,
                running: running.clone(),
                status: status_tx,
                policy,
                wanted: frame_wanted.clone(),
                watchers: watchers.clone(),
                floor_mm,
                compensate_latency,
                record: record.clone(),
            };
            thread::Builder::new()
                .name("vl-camera".into())
                .spawn(move || camera_loop.run())
                .expect("the OS starts a thread");
        }
        Lab {
            info,
            requests,
            feedback,
            frames,
            watchers,
            finished,
            status,
            running,
            frame_wanted,
            record,
            since_ns: vl_record::unix_ns_at(since),
            log: tokio::sync::broadcast::channel(LOG_LINES).0,
        }
    }

    /// What the processor gives the control loop and the serial guard.
    pub(crate) fn priorities(&self) -> Priorities {
        self.status.borrow().priority
    }

    /// Has the camera loop send its next frame, whatever the policy.
    pub(crate) fn request_frame(&self) {
        self.frame_wanted.store(true, Ordering::Relaxed);
    }

    /// Passes a request to the control loop.
    pub(crate) fn request(&self, request: LabRequest) {
        // The control loop only ends when this handle is dropped.
        let _ = self.requests.send(request);
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        self.running.store(false, Ordering::Relaxed);
    }
}
