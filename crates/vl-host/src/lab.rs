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
use tracing::{debug, warn};
use vl_core::{
    ARENA_CELL_MM, Arena, CSpace, CameraModel, Definition, Drive, EndReason, Footprint,
    FrameHeader, Grid, HostMessage, ImageFormat, MapField, Point, RobotModel, Summary, Teleop,
    Vector, WheelSpeeds,
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
/// How far ahead the virtual-obstacle guard looks.
const GUARD_LOOKAHEAD_S: f64 = 0.15;
/// Distance from the body within which the map's potential field pushes.
const MAP_FIELD_INFLUENCE_MM: f64 = 40.0;
/// Its strength: about 100 mm/s of push with the body 10 mm from a wall.
const MAP_FIELD_ETA: f64 = 1.0e5;

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
    /// A run begins; `assisted` runs add the potential fields to the
    /// operator's commands and feed the push back as a force.
    Start {
        definition: Definition,
        assisted: bool,
    },
    Drive {
        event: u64,
        drive: Drive,
    },
    Finish(EndReason),
}

/// A run ended; the session reports it.
#[derive(Debug, Clone)]
pub struct Finished(pub Summary);

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
    definition: Definition,
    started: Instant,
    last_command: Instant,
    distance_mm: f64,
    collisions: u64,
    wheels: WheelSpeeds,
    /// For an assisted run: the velocity the operator asks for, and the
    /// force last fed back.
    assist: Option<(Vector, [f64; 2])>,
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
}

impl Control {
    fn run(mut self) {
        let mut next_tick = Instant::now();
        let mut last_feedback = Instant::now();
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
            match self.robot.read() {
                Ok(reading) => self.observe(reading),
                Err(e) => {
                    warn!("{e}; stopping the run");
                    self.finish(EndReason::Fault);
                    continue;
                }
            }
            if commanded || last_feedback.elapsed() >= FEEDBACK_EVERY {
                self.publish();
                last_feedback = Instant::now();
            }
        }
    }

    /// Applies a request; true when it changed what the robot does.
    fn handle(&mut self, request: LabRequest) -> bool {
        match request {
            LabRequest::Start {
                definition,
                assisted,
            } => {
                self.event.store(0, Ordering::Relaxed);
                let now = Instant::now();
                self.run = Some(Run {
                    definition,
                    started: now,
                    last_command: now,
                    distance_mm: 0.0,
                    collisions: 0,
                    wheels: WheelSpeeds::default(),
                    assist: assisted.then_some((Vector::default(), [0.0; 2])),
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

    /// Sends the run's wheel speeds, unless the virtual-obstacle guard or
    /// the watchdog says otherwise.
    fn drive(&mut self) {
        let Some(run) = &mut self.run else { return };
        let stale = run.last_command.elapsed() > WATCHDOG;
        let mut wheels = run.wheels;
        if let (Some((desired, force)), Some(reading)) = (&mut run.assist, &self.last) {
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
            let wanted = if stale { Vector::default() } else { *desired };
            let assisted = self.teleop.assist(robot, wanted, field);
            *force = assisted.force;
            wheels = assisted.wheels;
        }
        if stale {
            wheels = WheelSpeeds::default();
        }
        if let Some(reading) = &self.last {
            wheels = guard(&self.info, &run.definition, reading, wheels);
        }
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
            }
        }
        let reached = run
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
            // Re-applying every tick lets the watchdog and guard act between commands.
            self.drive();
        }
    }

    /// Ends the run (if any): stops the robot and reports the summary.
    fn finish(&mut self, reason: EndReason) {
        self.halt();
        let Some(run) = self.run.take() else { return };
        let pose = self.last.as_ref().map(|r| r.pose).unwrap_or_default();
        let reached_goal = run
            .definition
            .goal
            .is_some_and(|g| pose.point().distance(g.point()) <= g.tolerance_mm);
        let summary = Summary {
            reason,
            reached_goal,
            events: self.event.load(Ordering::Relaxed),
            final_pose: pose,
            seconds: run.started.elapsed().as_secs_f64(),
            distance_mm: run.distance_mm,
            collisions: run.collisions,
        };
        debug!(?summary, "run finished");
        let _ = self.finished.send(Finished(summary));
        self.publish();
    }

    /// Stops the wheels; on failure there is nothing more software can do
    /// but say so.
    fn halt(&mut self) {
        self.sent = None;
        match self.robot.set_wheels(WheelSpeeds::default()) {
            Ok(()) => self.sent = Some(WheelSpeeds::default()),
            Err(e) => warn!("{e}: could not stop the robot"),
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

/// Keeps the robot out of the definition's virtual obstacles: if driving on
/// would bring the body into one, only the turning part of the motion is kept.
fn guard(
    info: &LabInfo,
    definition: &Definition,
    reading: &RobotReading,
    wheels: WheelSpeeds,
) -> WheelSpeeds {
    if definition.virtual_obstacles.is_empty() {
        return wheels;
    }
    let ahead = reading
        .pose
        .advance(wheels, info.robot.wheel_base_mm, GUARD_LOOKAHEAD_S);
    let blocked = |p: Point| {
        definition
            .virtual_obstacles
            .iter()
            .any(|o| o.distance(p) <= info.robot.radius_mm)
    };
    if blocked(ahead.point()) && !blocked(reading.pose.point()) {
        let turn = (wheels.right_mm_s - wheels.left_mm_s) / 2.0;
        WheelSpeeds {
            left_mm_s: -turn,
            right_mm_s: turn,
        }
    } else {
        wheels
    }
}

struct CameraLoop {
    camera: Box<dyn Camera>,
    frames: watch::Sender<Option<Bytes>>,
    event: Arc<AtomicU64>,
    since: Instant,
    running: Arc<AtomicBool>,
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
                Err(e) => warn!("{e}; no frame this period"),
            }
            thread::sleep(period.saturating_sub(started.elapsed()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Pose, Shape};

    #[test]
    fn the_guard_turns_instead_of_entering_a_virtual_obstacle() {
        let info = LabInfo {
            arena: Arena::navigation(),
            robot: RobotModel::khepera_ii(),
            camera: CameraModel {
                width_px: 320,
                height_px: 240,
                mm_per_px: 2.5,
                fps: 10.0,
            },
        };
        let definition = Definition {
            virtual_obstacles: vec![Shape::Circle {
                x_mm: 200.0,
                y_mm: 120.0,
                radius_mm: 20.0,
            }],
            ..Definition::default()
        };
        let reading = RobotReading {
            pose: Pose {
                x_mm: 130.0,
                y_mm: 120.0,
                theta_rad: 0.0,
            },
            wheels: WheelSpeeds::default(),
            proximity: vec![0; 8],
            contact: false,
        };
        let ahead = WheelSpeeds {
            left_mm_s: 300.0,
            right_mm_s: 300.0,
        };
        let guarded = guard(&info, &definition, &reading, ahead);
        assert_eq!(guarded.left_mm_s + guarded.right_mm_s, 0.0);
        let away = WheelSpeeds {
            left_mm_s: -300.0,
            right_mm_s: -300.0,
        };
        assert_eq!(guard(&info, &definition, &reading, away), away);
    }
}
