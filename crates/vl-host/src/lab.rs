//! Experiment control and sensed-data processing: the real-time loops that
//! turn commands into wheel speeds and robot and camera readings into
//! feedback and frames.
//!
//! Each loop runs on its own thread so a slow serial line or camera never
//! stalls the network side. They publish through `watch` channels, which keep
//! only the newest value: a slow client gets the latest feedback and frame,
//! never a queue of stale ones.

use std::io::Cursor;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread;
use std::time::{Duration, Instant};

use tokio::sync::{mpsc as async_mpsc, watch};
use tokio_tungstenite::tungstenite::Bytes;
use tracing::{debug, info, warn};
use vl_core::{
    ARENA_CELL_MM, Arena, CSpace, CameraModel, Definition, DeviceState, Drive, EndReason,
    Experiment, Footprint, FrameHeader, Grid, HostMessage, ImageFormat, MapField, RobotModel,
    Safety, Situation, Summary, Surroundings, Teleop, Vector, WheelSpeeds,
};

use crate::drivers::{Camera, Robot, RobotReading};

/// The control period: the Khepera's speed-controller period.
const TICK: Duration = Duration::from_millis(10);
/// Feedback is published at least this often while nothing else changes.
const FEEDBACK_EVERY: Duration = Duration::from_millis(20);
/// A running robot with no new command for this long stops by itself.
pub const WATCHDOG: Duration = Duration::from_millis(500);
/// Width of the arena drawing a Guest gets when the lab has no camera.
const NO_CAMERA_WIDTH_PX: u32 = 640;
/// The safety layer assumes a command lasts at least this long before the
/// next can brake it: three control periods.
const REACTION: Duration = Duration::from_millis(30);
/// A command asks the robot to move when its mean wheel speed is above this, mm/s.
const MOVING_MM_S: f64 = 1.0;
/// Distance from the body within which the map's potential field pushes.
const MAP_FIELD_INFLUENCE_MM: f64 = 40.0;
/// Its strength: about 100 mm/s of push with the body 10 mm from a wall.
const MAP_FIELD_ETA: f64 = 1.0e5;

/// How long the first retry of a lost robot or camera waits; each next
/// waits twice as long, up to `RETRY_MAX`.
const RETRY_FIRST: Duration = Duration::from_millis(100);
const RETRY_MAX: Duration = Duration::from_secs(5);

/// Whether the lab's devices answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabStatus {
    pub robot: DeviceState,
    pub camera: DeviceState,
}

impl LabStatus {
    pub fn message(&self) -> HostMessage {
        HostMessage::Status {
            robot: self.robot,
            camera: self.camera,
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

/// What the lab is, as the Guest needs it at mount.
#[derive(Debug, Clone)]
pub struct LabInfo {
    pub arena: Arena,
    pub robot: RobotModel,
    pub camera: CameraModel,
}

/// Requests from the session to the control loop.
#[derive(Debug)]
pub enum LabRequest {
    /// A run of `experiment` begins. Teleoperation adds the potential
    /// fields to the operator's commands and feeds the push back as a
    /// force; navigation ends when the robot reaches the goal.
    Start {
        /// The run's number, which its `Finished` carries back.
        run: u64,
        definition: Definition,
        experiment: Experiment,
    },
    Drive {
        event: u64,
        drive: Drive,
    },
    Finish(EndReason),
}

/// Run number `.0` ended; the session reports it.
#[derive(Debug, Clone)]
pub struct Finished(pub u64, pub Summary);

/// The session's handle on the running lab.
pub struct Lab {
    pub info: LabInfo,
    requests: mpsc::Sender<LabRequest>,
    /// Newest robot feedback.
    pub feedback: watch::Receiver<Option<HostMessage>>,
    /// Newest camera frame, encoded for the wire.
    pub frames: watch::Receiver<Option<Bytes>>,
    /// Runs that ended.
    pub finished: async_mpsc::UnboundedReceiver<Finished>,
    /// Whether the robot and the camera answer.
    pub status: watch::Receiver<LabStatus>,
    running: Arc<AtomicBool>,
}

impl Lab {
    /// Starts the control and camera loops on their own threads. Without a
    /// camera no frames are sent; the model still maps the arena for drawing.
    pub fn spawn(robot: Box<dyn Robot>, camera: Option<Box<dyn Camera>>, arena: Arena) -> Lab {
        let model = match &camera {
            Some(camera) => camera.model(),
            None => CameraModel::overhead(arena.width_mm, arena.height_mm, NO_CAMERA_WIDTH_PX, 0.0),
        };
        let info = LabInfo {
            arena,
            robot: robot.model().clone(),
            camera: model,
        };
        let (requests, request_rx) = mpsc::channel();
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
        });
        let status_tx = Arc::new(status_tx);
        let running = Arc::new(AtomicBool::new(true));
        let event = Arc::new(AtomicU64::new(0));
        let since = Instant::now();
        let control = Control {
            robot,
            info: info.clone(),
            requests: request_rx,
            feedback: feedback_tx,
            finished: finished_tx,
            event: event.clone(),
            since,
            run: None,
            last: None,
            sent: None,
            teleop: Teleop::default(),
            map_field: map_field(&info),
            surroundings: Surroundings::new(&info.arena),
            period: TICK,
            status: status_tx.clone(),
            retry: None,
        };
        thread::Builder::new()
            .name("vl-control".into())
            .spawn(move || control.run())
            .expect("the OS starts a thread");
        if let Some(camera) = camera {
            let camera_loop = CameraLoop {
                camera,
                frames: frames_tx,
                event,
                since,
                running: running.clone(),
                status: status_tx,
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
            finished,
            status,
            running,
        }
    }

    /// Passes a request to the control loop.
    pub fn request(&self, request: LabRequest) {
        // The control loop only ends when this handle is dropped.
        let _ = self.requests.send(request);
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        self.running.store(false, Ordering::Relaxed);
    }
}

/// One run of an experiment, from `start` to its end.
struct Run {
    number: u64,
    definition: Definition,
    experiment: Experiment,
    /// The arena and the definition's virtual obstacles, for the safety layer.
    surroundings: Surroundings,
    started: Instant,
    last_command: Instant,
    distance_mm: f64,
    collisions: u64,
    /// The wheel speeds the last command asks for.
    wheels: WheelSpeeds,
    /// For an assisted run: the velocity the operator asks for, and the
    /// force last fed back.
    assist: Option<(Vector, [f64; 2])>,
    /// Whether the safety layer changed the last command it saw.
    limited: bool,
    /// The body's least clearance seen, mm.
    closest_mm: f64,
    /// Sum and count, over periods in which a command asked to move, of the
    /// forward speed the layer let through over the speed asked.
    kept: (f64, u64),
}

impl Run {
    fn summary(&self, reason: EndReason, events: u64, reading: Option<&RobotReading>) -> Summary {
        let pose = reading.map(|r| r.pose).unwrap_or_default();
        Summary {
            reason,
            reached_goal: self
                .definition
                .goal
                .is_some_and(|g| pose.point().distance(g.point()) <= g.tolerance_mm),
            events,
            final_pose: pose,
            seconds: self.started.elapsed().as_secs_f64(),
            distance_mm: self.distance_mm,
            collisions: self.collisions,
            closest_mm: self.closest_mm.is_finite().then_some(self.closest_mm),
            speed_kept: (self.kept.1 > 0).then(|| self.kept.0 / self.kept.1 as f64),
        }
    }
}

struct Control {
    robot: Box<dyn Robot>,
    info: LabInfo,
    requests: mpsc::Receiver<LabRequest>,
    feedback: watch::Sender<Option<HostMessage>>,
    finished: async_mpsc::UnboundedSender<Finished>,
    /// The last command's event number, shared with the camera loop.
    event: Arc<AtomicU64>,
    since: Instant,
    run: Option<Run>,
    last: Option<RobotReading>,
    /// What the wheels were last told, so an unchanged command is not resent.
    sent: Option<WheelSpeeds>,
    teleop: Teleop,
    /// The arena's repulsive field, over the C-space of the robot's body.
    map_field: Option<MapField>,
    /// The arena's walls and obstacles, to which each run adds its virtual ones.
    surroundings: Surroundings,
    /// How long the last control period really took.
    period: Duration,
    /// Whether the robot and camera answer, shared with the camera loop.
    status: Arc<watch::Sender<LabStatus>>,
    /// While the robot's link is down: when to try it again.
    retry: Option<Retry>,
}

impl Control {
    fn run(mut self) {
        let mut next_tick = Instant::now();
        let mut last_feedback = Instant::now();
        let mut last_read = Instant::now();
        loop {
            let mut commanded = false;
            loop {
                let wait = next_tick.saturating_duration_since(Instant::now());
                match self.requests.recv_timeout(wait) {
                    Ok(request) => commanded |= self.handle(request),
                    Err(RecvTimeoutError::Timeout) => break,
                    Err(RecvTimeoutError::Disconnected) => {
                        self.halt();
                        return;
                    }
                }
            }
            next_tick += TICK;
            if next_tick < Instant::now() {
                next_tick = Instant::now() + TICK;
            }
            self.period = last_read.elapsed();
            last_read = Instant::now();
            if let Some(retry) = &mut self.retry {
                if !retry.due() {
                    continue;
                }
                match self.robot.reconnect() {
                    Ok(()) => {
                        info!("the robot answers again");
                        self.retry = None;
                        self.status.send_modify(|s| s.robot = DeviceState::Online);
                    }
                    Err(e) => {
                        debug!("the robot still does not answer: {e}");
                        continue;
                    }
                }
            }
            match self.robot.read() {
                Ok(reading) => self.observe(reading),
                Err(e) => {
                    warn!("{e}; the robot is offline until it answers again");
                    self.retry = Some(Retry::new());
                    self.status.send_modify(|s| s.robot = DeviceState::Offline);
                    self.finish(EndReason::Fault);
                    continue;
                }
            }
            // Ticks come every TICK: publish on the one nearest the period.
            if commanded || last_feedback.elapsed() + TICK / 2 >= FEEDBACK_EVERY {
                self.publish();
                last_feedback = Instant::now();
            }
        }
    }

    /// Applies a request; true when it changed what the robot does.
    fn handle(&mut self, request: LabRequest) -> bool {
        match request {
            LabRequest::Start {
                run,
                definition,
                experiment,
            } => {
                self.event.store(0, Ordering::Relaxed);
                let now = Instant::now();
                self.run = Some(Run {
                    number: run,
                    surroundings: self.surroundings.with(&definition.virtual_obstacles),
                    definition,
                    experiment,
                    started: now,
                    last_command: now,
                    distance_mm: 0.0,
                    collisions: 0,
                    wheels: WheelSpeeds::default(),
                    assist: experiment
                        .assists_the_operator()
                        .then_some((Vector::default(), [0.0; 2])),
                    limited: false,
                    closest_mm: f64::INFINITY,
                    kept: (0.0, 0),
                });
                false
            }
            LabRequest::Drive { event, drive } => {
                let Some(run) = self.run.as_mut() else {
                    return false;
                };
                let mut wheels = drive.wheels(&self.info.robot);
                if let Some(limit) = run.definition.max_speed_mm_s {
                    let mut capped = self.info.robot.clone();
                    capped.max_wheel_speed_mm_s = capped.max_wheel_speed_mm_s.min(limit);
                    wheels = capped.clamp(wheels);
                }
                run.wheels = wheels;
                if let Some((desired, _)) = &mut run.assist {
                    let robot = &self.info.robot;
                    let v = (wheels.left_mm_s + wheels.right_mm_s) / 2.0;
                    let w = (wheels.right_mm_s - wheels.left_mm_s) / robot.wheel_base_mm;
                    *desired = self.teleop.velocity_for(robot, v, w);
                }
                run.last_command = Instant::now();
                self.event.store(event, Ordering::Relaxed);
                self.drive();
                true
            }
            LabRequest::Finish(reason) => {
                self.finish(reason);
                true
            }
        }
    }

    /// Sends the run's wheel speeds, as the watchdog, the assistance and
    /// then the safety layer leave them; between runs, holds the robot.
    fn drive(&mut self) {
        let Some(run) = &mut self.run else { return };
        let Some(reading) = &self.last else {
            // Nothing is known of where the robot is yet: it stays put.
            return;
        };
        let stale = run.last_command.elapsed() > WATCHDOG;
        let mut wanted = if stale {
            WheelSpeeds::default()
        } else {
            run.wheels
        };
        if let Some((desired, force)) = &mut run.assist {
            let robot = &self.info.robot;
            let ahead = self.map_field.as_ref().map_or(Vector::default(), |f| {
                f.guidance(reading.pose.point())
                    .rotated(reading.pose.theta_rad)
            });
            let sensed = self.teleop.sensor_field(robot, &reading.proximity);
            let field = Vector {
                x: sensed.x + ahead.x,
                y: sensed.y + ahead.y,
            };
            let asked = if stale { Vector::default() } else { *desired };
            let assisted = self.teleop.assist(robot, asked, field);
            *force = assisted.force;
            wanted = assisted.wheels;
        }
        // Whatever asked for `wanted`, the robot must be able to stop in time.
        let safety = Safety {
            reaction_s: REACTION.max(self.period.mul_f64(1.5)).as_secs_f64(),
            ..Safety::default()
        };
        let situation = Situation {
            pose: reading.pose,
            wheels: reading.wheels,
            proximity: &reading.proximity,
        };
        let guarded = safety.guard(&self.info.robot, &run.surroundings, situation, wanted);
        run.limited = guarded.limited;
        run.closest_mm = run.closest_mm.min(guarded.clearance_mm);
        let asked = (wanted.left_mm_s + wanted.right_mm_s) / 2.0;
        if asked.abs() > MOVING_MM_S {
            let let_through = (guarded.wheels.left_mm_s + guarded.wheels.right_mm_s) / 2.0;
            run.kept.0 += (let_through / asked).clamp(0.0, 1.0);
            run.kept.1 += 1;
        }
        let wheels = guarded.wheels;
        if self.sent == Some(wheels) {
            return;
        }
        match self.robot.set_wheels(wheels) {
            Ok(()) => self.sent = Some(wheels),
            Err(e) => {
                warn!("{e}; stopping the run");
                self.finish(EndReason::Fault);
            }
        }
    }

    /// Takes in a reading: bookkeeping, goal, time limit, watchdog.
    fn observe(&mut self, reading: RobotReading) {
        let previous = self.last.replace(reading.clone());
        let Some(run) = self.run.as_mut() else { return };
        if let Some(prev) = previous {
            run.distance_mm += prev.pose.point().distance(reading.pose.point());
            if reading.contact && !prev.contact {
                run.collisions += 1;
                warn!(
                    "contact at ({:.0}, {:.0}) mm: the safety layer lets only moves away through",
                    reading.pose.x_mm, reading.pose.y_mm
                );
            }
        }
        // A navigation run ends at its goal; in teleoperation a goal is a
        // target the summary reports on, and the operator ends the run.
        let reached = run.experiment == Experiment::Navigation
            && run
                .definition
                .goal
                .is_some_and(|g| reading.pose.point().distance(g.point()) <= g.tolerance_mm);
        let timed_out = run
            .definition
            .time_limit_s
            .is_some_and(|limit| run.started.elapsed().as_secs_f64() > limit);
        if reached {
            self.finish(EndReason::GoalReached);
        } else if timed_out {
            self.finish(EndReason::TimeLimit);
        } else {
            // Re-applying every tick lets the watchdog and the safety layer act between commands.
            self.drive();
        }
    }

    /// Ends the run (if any): stops the robot and reports the summary.
    fn finish(&mut self, reason: EndReason) {
        self.halt();
        let Some(run) = self.run.take() else { return };
        let summary = run.summary(
            reason,
            self.event.load(Ordering::Relaxed),
            self.last.as_ref(),
        );
        debug!(?summary, "run finished");
        let _ = self.finished.send(Finished(run.number, summary));
        self.publish();
    }

    /// Stops the wheels; on failure there is nothing more software can do
    /// but say so (once: an offline robot is retried, not shouted at).
    fn halt(&mut self) {
        self.sent = None;
        match self.robot.set_wheels(WheelSpeeds::default()) {
            Ok(()) => self.sent = Some(WheelSpeeds::default()),
            Err(e) if self.retry.is_none() => warn!("{e}: could not stop the robot"),
            Err(_) => {}
        }
    }

    fn publish(&self) {
        let Some(reading) = &self.last else { return };
        let message = HostMessage::Feedback {
            event: self.event.load(Ordering::Relaxed),
            t_ms: self.since.elapsed().as_secs_f64() * 1e3,
            pose: reading.pose,
            wheels: reading.wheels,
            proximity: reading.proximity.clone(),
            contact: reading.contact,
            force: self.run.as_ref().and_then(|r| r.assist).map(|(_, f)| f),
            limited: self.run.as_ref().is_some_and(|r| r.limited),
        };
        self.feedback.send_replace(Some(message));
    }
}

/// The arena's potential field for assisted teleoperation: repulsive from
/// the C-space obstacles of the robot's body, so the push depends on how far
/// the body (not its centre) is from a wall.
fn map_field(info: &LabInfo) -> Option<MapField> {
    let footprint = Footprint::Disc {
        radius_mm: info.robot.radius_mm,
    };
    let grown = Grid::from_arena(&info.arena, ARENA_CELL_MM)
        .and_then(|grid| CSpace::build(&grid, footprint, 1));
    match grown {
        Ok(cspace) => Some(MapField::new(
            cspace.grid(),
            MAP_FIELD_INFLUENCE_MM,
            MAP_FIELD_ETA,
        )),
        // An arena that cannot be gridded (it was checked on loading) gets
        // no map guidance; the sensors' field still acts.
        Err(e) => {
            warn!("no map field for assisted teleoperation: {e}");
            None
        }
    }
}

struct CameraLoop {
    camera: Box<dyn Camera>,
    frames: watch::Sender<Option<Bytes>>,
    event: Arc<AtomicU64>,
    since: Instant,
    running: Arc<AtomicBool>,
    status: Arc<watch::Sender<LabStatus>>,
}

impl CameraLoop {
    fn run(mut self) {
        let model = self.camera.model();
        let period = Duration::from_secs_f64(1.0 / model.fps.max(0.1));
        let mut seq = 0u64;
        while self.running.load(Ordering::Relaxed) {
            let started = Instant::now();
            let capture_us = self.since.elapsed().as_micros() as u64;
            let event = self.event.load(Ordering::Relaxed);
            match self.camera.grab() {
                Ok(image) => {
                    let mut png = Cursor::new(Vec::new());
                    if let Err(e) = image.write_to(&mut png, image::ImageFormat::Png) {
                        warn!("could not encode a camera frame: {e}");
                    } else {
                        seq += 1;
                        let header = FrameHeader {
                            format: ImageFormat::Png,
                            width: image.width() as u16,
                            height: image.height() as u16,
                            seq,
                            event,
                            capture_us,
                        };
                        let wire = header.encode(png.get_ref());
                        self.frames.send_replace(Some(Bytes::from(wire)));
                    }
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
