//! Experiment control (the thesis's Experiment Control, at the Host): every
//! control period it folds the camera's sightings and the wheels' odometry
//! into the pose estimate, follows the defined path or the operator's
//! commands, and passes what the wheels are asked through the safety layer.
//! It steers only by the estimate: nothing here can see the simulator's
//! truth, which a `Witness` gives the run's record alone.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use tokio::sync::{mpsc as async_mpsc, watch};
use tracing::{debug, info, warn};
use vl_core::{
    CSpace, DeviceState, EndReason, Feedback, Fold, HeldBack, HostMessage, Leash, Localiser,
    MapField, Pose, PoseSource, Priorities, RobotModel, Safety, Situation, Surroundings, Teleop,
    Told, Uncertainty, Vector, WATCHDOG, WheelSpeeds, wrap_angle,
};

use super::camera::Sighting;
use super::controller::{self, Beside, STALE, Said};
use super::run::Run;
use super::{Finished, LabInfo, LabRequest, LabStatus, Retry, TICK};
use crate::drivers::{Robot, RobotError, RobotReading, Witness};
use vl_record::{Feed, Recordable};

/// The shortest time between two control periods: a command acted on at
/// once still waits this long after the last period.
const TICK_GAP: Duration = Duration::from_millis(2);
/// Feedback is published at least this often while nothing else changes.
const FEEDBACK_EVERY: Duration = Duration::from_millis(20);
/// Each leash lasts at least this long before the next extends it: three
/// control periods (more on a slow line: half as long again as a period).
const HOLD: Duration = Duration::from_millis(30);
/// A command asks the robot to move when its mean wheel speed is above this, mm/s.
const MOVING_MM_S: f64 = 1.0;
/// An assisted run let through less than this share of the forward speed
/// asked is held back from it.
const HELD_SHARE: f64 = 0.5;
/// Distance from the body within which the map's potential field pushes.
const MAP_FIELD_INFLUENCE_MM: f64 = 40.0;
/// Its strength: about 100 mm/s of push with the body 10 mm from a wall.
const MAP_FIELD_ETA: f64 = 1.0e5;
/// The safety margin widens by this many standard deviations of the pose
/// estimate…
const UNCERTAINTY_SIGMAS: f64 = 2.0;
/// …of at most this, mm: an estimate this unsure keeps the robot well
/// away from everything mapped, and its sensors guard the rest.
const MAX_UNCERTAINTY_MM: f64 = 50.0;
/// A pose is the camera's while its last sighting is this recent, s.
const SIGHTING_FRESH_S: f64 = 0.5;
/// A run that ends facing a heading is there within this, rad (6°)…
const FACING_RAD: f64 = 0.1;
/// …turning at most this fast, rad/s, and with the wheels at least this
/// fast, mm/s, so a real robot's speed steps do not round the turn to nothing.
const FACE_TURN_RAD_S: f64 = 1.5;
const FACE_MIN_WHEEL_MM_S: f64 = 8.0;
/// A run whose robot the camera has not seen for this long, s, stops: the
/// odometry it drove on meanwhile drifts too far to keep it off obstacles.
const ROBOT_LOST_S: f64 = 2.0;
/// The camera, disagreeing with the odometry frame after frame, moved the
/// estimate this far or turned it this much in three seconds: beyond slip and
/// jitter, so the odometry (or the robot's wheels) cannot be trusted and
/// the run stops.
const CONTRADICTION_MM: f64 = 50.0;
const CONTRADICTION_RAD: f64 = 0.5;
/// A followed run that comes no further than `HeldBack::CREEP_MM` along
/// its path in this long, s, is held back for good: it ends, saying why.
const HELD_BACK: Duration = Duration::from_secs(5);
/// How far ahead along the path the room it leaves is looked for, mm.
const ROOM_AHEAD_MM: f64 = 60.0;

pub(crate) struct Control {
    robot: Box<dyn Robot>,
    info: LabInfo,
    requests: mpsc::Receiver<LabRequest>,
    /// The robot as the camera loop locates it; none without a camera.
    sightings: Option<Receiver<Sighting>>,
    localiser: Localiser,
    /// What only a simulator knows, for the run's record.
    witness: Option<Box<dyn Witness>>,
    feedback: watch::Sender<Option<HostMessage>>,
    finished: async_mpsc::UnboundedSender<Finished>,
    /// The last command's event number, shared with the camera loop.
    event: Arc<AtomicU64>,
    since: Instant,
    run: Option<Run>,
    last: Option<Observed>,
    /// The last leash the robot took, and the wheels' travel its reach
    /// counts from; none when it is not known (a stop is not resent).
    sent: Option<(Leash, [f64; 2])>,
    teleop: Teleop,
    /// The arena's walls and obstacles, to which each run adds its virtual ones.
    surroundings: Surroundings,
    /// How long the last control period really took.
    period: Duration,
    /// Whether the robot and camera answer, shared with the camera loop.
    status: Arc<watch::Sender<LabStatus>>,
    /// While the robot's link is down: when to try it again.
    retry: Option<Retry>,
    /// The recorder, handed every feedback while a run is recorded, with
    /// the simulator's truth at its reading (for the record alone).
    record: Feed,
    truth: Option<Pose>,
}

/// The robot's last reading, and the pose estimated after it.
struct Observed {
    reading: RobotReading,
    pose: Pose,
}

/// What the control loop is given to work with.
pub(crate) struct Wiring {
    pub requests: mpsc::Receiver<LabRequest>,
    pub sightings: Option<Receiver<Sighting>>,
    pub feedback: watch::Sender<Option<HostMessage>>,
    pub finished: async_mpsc::UnboundedSender<Finished>,
    pub event: Arc<AtomicU64>,
    pub status: Arc<watch::Sender<LabStatus>>,
    pub since: Instant,
    pub record: Feed,
}

impl Control {
    /// Control of `robot` in the lab `info` describes, believing the robot
    /// is at `seen` (a first sighting: when, and where) or else at the
    /// map's start.
    pub(crate) fn new(
        robot: Box<dyn Robot>,
        witness: Option<Box<dyn Witness>>,
        info: LabInfo,
        seen: Option<(Instant, Pose)>,
        wiring: Wiring,
    ) -> Control {
        // Without a camera the robot is where the lab says it was put; with
        // one, the camera says.
        let start = info.arena.start;
        let uncertainty = Uncertainty::for_robot(&info.robot);
        let mut localiser = if wiring.sightings.is_some() {
            Localiser::new(start, uncertainty)
        } else {
            Localiser::placed(start, uncertainty)
        };
        if let Some((taken, pose)) = seen {
            let at = taken.saturating_duration_since(wiring.since).as_secs_f64();
            localiser.sighting(at, pose);
        }
        Control {
            robot,
            surroundings: Surroundings::new(&info.arena),
            info,
            requests: wiring.requests,
            sightings: wiring.sightings,
            localiser,
            witness,
            feedback: wiring.feedback,
            finished: wiring.finished,
            event: wiring.event,
            since: wiring.since,
            run: None,
            last: None,
            sent: None,
            teleop: Teleop::default(),
            period: TICK,
            status: wiring.status,
            retry: None,
            record: wiring.record,
            truth: None,
        }
    }

    /// Seconds on the lab's clock at `t`.
    fn clock(&self, t: Instant) -> f64 {
        t.saturating_duration_since(self.since).as_secs_f64()
    }

    /// Where the pose estimate comes from now.
    fn source(&self) -> PoseSource {
        let now = self.clock(Instant::now());
        match self.localiser.since_sighting(now) {
            Some(age) if self.sightings.is_some() && age <= SIGHTING_FRESH_S => PoseSource::Camera,
            _ => PoseSource::Odometry,
        }
    }

    /// Raises this thread (the control loop's) as far as the system
    /// allows; says what it and the robot's serial guard got.
    pub(crate) fn raise(&self) -> Priorities {
        Priorities {
            control: crate::priority::raise_for_control("control loop"),
            guard: self.robot.guard_priority(),
        }
    }

    pub(crate) fn run(mut self) {
        let mut next_tick = Instant::now();
        let mut last_feedback = Instant::now();
        let mut last_read = Instant::now();
        loop {
            let mut commanded = false;
            // Event-based control answers an event, not a clock: a request
            // that changes what the robot does is acted on at once (with
            // whatever came with it, the newest winning), and its feedback
            // published, rather than at the next period's end.
            while !commanded {
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
            while let Ok(request) = self.requests.try_recv() {
                commanded |= self.handle(request);
            }
            // However fast commands come, the robot is read at most so often.
            std::thread::sleep((last_read + TICK_GAP).saturating_duration_since(Instant::now()));
            next_tick = Instant::now() + TICK;
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
                        let guard = self.robot.guard_priority();
                        self.status.send_modify(|s| {
                            s.robot = DeviceState::Online;
                            s.priority.guard = guard;
                        });
                    }
                    Err(e) => {
                        debug!("the robot still does not answer: {e}");
                        continue;
                    }
                }
            }
            self.take_sightings();
            match self.robot.read() {
                Ok(reading) => self.observe(reading),
                Err(e) => {
                    warn!("{e}; the robot is offline until it answers again");
                    self.retry = Some(Retry::new());
                    self.status.send_modify(|s| s.robot = DeviceState::Offline);
                    self.fail(&e);
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
                conduct,
                field,
                face,
                controller,
            } => {
                self.event.store(0, Ordering::Relaxed);
                let surroundings = self.surroundings.with(&definition.virtual_obstacles);
                let mut started = Run::new(run, *definition, conduct, surroundings, field, face);
                started.controller = controller.map(Beside::spawn);
                if started.follower.is_some() {
                    info!(run, "following the defined path from the camera's estimate");
                }
                self.run = Some(started);
                false
            }
            LabRequest::Drive { event, drive } => {
                let Some(run) = self.run.as_mut() else {
                    return false;
                };
                let wheels =
                    (run.definition).capped(&self.info.robot, drive.wheels(&self.info.robot));
                run.wheels = wheels;
                run.commanded = true;
                if let Some(assist) = &mut run.assist {
                    let robot = &self.info.robot;
                    let w = (wheels.right_mm_s - wheels.left_mm_s) / robot.wheel_base_mm;
                    assist.desired = self.teleop.velocity_for(robot, wheels.forward_mm_s(), w);
                }
                run.last_command = Instant::now();
                self.event.store(event, Ordering::Relaxed);
                // The newest command wins: it reaches the wheels on the next
                // tick, and whatever came before it is forgotten, so nothing
                // queues behind a slow line.
                true
            }
            LabRequest::Hold(held) => {
                let Some(run) = self.run.as_mut() else {
                    return false;
                };
                run.held = held;
                // Back from a dropped link, the operator starts afresh:
                // nothing sent before counts as fresh.
                run.commanded = false;
                run.wheels = WheelSpeeds::default();
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
        let margin_mm = self.margin_mm();
        let Some(run) = &mut self.run else { return };
        let Some(Observed { reading, pose }) = &self.last else {
            // Nothing is known of where the robot is yet: it stays put.
            return;
        };
        let pose = *pose;
        // A held run is as still as one whose commands went stale; a
        // controller's go stale within a few of its steps.
        let watchdog = if run.controller.is_some() {
            STALE
        } else {
            WATCHDOG
        };
        let stale = run.held || run.last_command.elapsed() > watchdog;
        let mut wanted = match &mut run.follower {
            _ if run.held => WheelSpeeds::default(),
            // At the goal the robot first stops where it is — at once, by the
            // speed controller: a leashed turn would brake its way forward
            // only as fast as the profile — then turns in place.
            _ if run.turning && still_rolling(reading.wheels) => WheelSpeeds::default(),
            _ if run.turning => {
                let face = run.face.unwrap_or(pose.theta_rad);
                turn_towards(&self.info.robot, pose.theta_rad, face)
            }
            // The operator's fresh command takes over from the path.
            Some(follower) if !run.commanded || stale => {
                let along = follower.step(&self.info.robot, pose, &reading.proximity);
                run.definition.capped(&self.info.robot, along.wheels())
            }
            _ if stale => WheelSpeeds::default(),
            _ => run.wheels,
        };
        // What was asked, before the assistance eases it.
        let asked_wheels = wanted;
        if let Some(assist) = &mut run.assist {
            let robot = &self.info.robot;
            let ahead = run.field.as_ref().map_or(Vector::default(), |f| {
                f.guidance(pose.point()).rotated(pose.theta_rad)
            });
            let sensed = self.teleop.sensor_field(robot, &reading.proximity);
            let field = Vector {
                x: sensed.x + ahead.x,
                y: sensed.y + ahead.y,
            };
            let asked = if stale {
                Vector::default()
            } else {
                assist.desired
            };
            let assisted = self.teleop.assist(robot, asked, field);
            assist.force = assisted.force;
            wanted = assisted.wheels;
        }
        // Whatever asked for `wanted`, the robot must be able to stop in
        // time, wherever near the estimate it may be (`margin_mm`).
        // The command lasts until the next one reaches the wheels, a control
        // period or more; it reaches them only after the reads since the
        // odometry was sampled and its own exchange on the line.
        let safety = Safety {
            hold_s: HOLD.max(self.period.mul_f64(1.5)).as_secs_f64(),
            delay_s: (reading.taken.elapsed() + self.robot.command_latency()).as_secs_f64(),
            margin_mm,
        };
        let situation = Situation {
            pose,
            wheels: reading.wheels,
            told: Told::seen_from(self.sent, reading.travel_mm),
            proximity: &reading.proximity,
        };
        let guarded = safety.guard(&self.info.robot, &run.surroundings, situation, wanted);
        // A contact is what the Host knows of: the robot's own sense of
        // touch, or the body at or past something by the estimate and the
        // proximity readings. The summary counts each touch once.
        let touching = reading.contact || guarded.clearance_mm <= 0.0;
        if touching && !run.touching {
            run.collisions += 1;
            warn!(
                "contact at ({:.0}, {:.0}) mm: the safety layer lets only moves away through",
                pose.x_mm, pose.y_mm
            );
        }
        run.touching = touching;
        // In an assisted run the obstacles' push may stop the robot short of
        // them before the layer has to: an operator pushing on is held back
        // from what they ask all the same, and is told so.
        let pushed_back = run.assist.is_some()
            && asked_wheels.forward_mm_s().abs() > MOVING_MM_S
            && guarded.wheels.forward_mm_s() / asked_wheels.forward_mm_s() < HELD_SHARE;
        run.limited = guarded.limited || pushed_back;
        run.closest_mm = run.closest_mm.min(guarded.clearance_mm);
        let asked = wanted.forward_mm_s();
        if asked.abs() > MOVING_MM_S {
            run.kept.add(asked, guarded.wheels.forward_mm_s());
        }
        // A leash is extended every period; a stop is said once.
        let leash = guarded.leash;
        if leash.is_stop() && self.sent.is_some_and(|(sent, _)| sent.is_stop()) {
            return;
        }
        let from = reading.travel_mm;
        match self.robot.drive(&leash) {
            Ok(()) => self.sent = Some((leash, from)),
            Err(e) => {
                warn!("{e}; stopping the run");
                self.fail(&e);
            }
        }
    }

    /// Folds the camera's newest sightings into the estimate.
    fn take_sightings(&mut self) {
        let Some(sightings) = &self.sightings else {
            return;
        };
        let seen: Vec<Sighting> = sightings.try_iter().collect();
        for sighting in seen {
            let at = self.clock(sighting.taken);
            let fold = self.localiser.sighting(at, sighting.pose);
            if fold != Fold::Reset || !sighting.dated || self.run.is_none() {
                continue;
            }
            let (moved, turned) = self.localiser.overruled();
            if moved > CONTRADICTION_MM || turned > CONTRADICTION_RAD {
                let why = format!(
                    "the camera keeps seeing the robot elsewhere: it moved the estimate {moved:.0} mm and turned it {turned:.2} rad in 3 s"
                );
                warn!("{why}; stopping the run");
                self.fail(&RobotError::Untrusted(why));
            }
        }
    }

    /// Takes in a reading: estimate, bookkeeping, goal, time limit, lost
    /// robot, watchdog.
    fn observe(&mut self, reading: RobotReading) {
        let now = self.clock(Instant::now());
        self.localiser.odometry(now, reading.odometry);
        if self.source() == PoseSource::Odometry {
            // No camera to say: the sensors against the map keep the
            // estimate from drifting across a corridor.
            self.localiser
                .ranges(&self.info.robot, &self.info.arena, &reading.proximity);
        }
        let pose = self.localiser.pose();
        let previous = self.last.replace(Observed {
            reading: reading.clone(),
            pose,
        });
        let Some(run) = self.run.as_mut() else { return };
        let truth = self.witness.as_mut().map(|w| w.true_pose());
        run.record.record(pose, truth);
        self.truth = truth;
        if let Some(previous) = previous {
            run.distance_mm += previous.pose.point().distance(pose.point());
        }
        // A run whose success is the goal (or its waypoints) ends there;
        // otherwise a goal is a target the summary reports on, and the
        // operator ends the run.
        run.visited = run.visited.at(&run.definition, pose.point());
        let reached = run.turning
            || run.conduct.ends_at_goal && run.definition.reached(run.visited, pose.point());
        let timed_out = run
            .definition
            .time_limit_s
            .is_some_and(|limit| run.started.elapsed().as_secs_f64() > limit);
        // Unseen since the last sighting, or since the run began if later.
        let unseen_s = self
            .localiser
            .since_sighting(now)
            .unwrap_or(f64::INFINITY)
            .min(run.started.elapsed().as_secs_f64());
        let lost = self.sightings.is_some() && unseen_s > ROBOT_LOST_S;
        let said = self.tend_controller(pose, &reading);
        let Some(run) = self.run.as_mut() else { return };
        let facing = run
            .face
            .is_none_or(|face| wrap_angle(face - pose.theta_rad).abs() <= FACING_RAD);
        if reached && !facing {
            // At the goal, not yet facing its heading: turn in place.
            run.turning = true;
            self.drive();
        } else if reached {
            self.finish(EndReason::GoalReached);
        } else if timed_out {
            self.finish(EndReason::TimeLimit);
        } else if let Some(reason) = said {
            self.finish(reason);
        } else if lost {
            warn!("the camera has not seen the robot for {unseen_s:.1} s: stopping the run");
            self.finish(EndReason::RobotLost);
        } else if let Some(held) = self.held_back(pose) {
            warn!("{held}: stopping the run");
            if let Some(run) = self.run.as_mut() {
                run.held_back = Some(held);
            }
            self.finish(EndReason::HeldBack);
        } else {
            // Re-applying every tick lets the watchdog and the safety layer act between commands.
            self.drive();
        }
    }

    /// Offers the run's controller its observation when a step is due and
    /// takes what it said: its command (within the definition's cap), or
    /// the fault (or its being done) that ends the run.
    fn tend_controller(&mut self, pose: Pose, reading: &RobotReading) -> Option<EndReason> {
        let at = (pose, self.uncertain_mm());
        let robot = &self.info.robot;
        let run = self.run.as_mut()?;
        let beside = run.controller.as_mut()?;
        let (started, definition) = (run.started, &run.definition);
        beside.offer(|| controller::observation(started, definition, robot, at, reading));
        match beside.said(&self.record) {
            Said::Nothing => None,
            Said::Wheels(asked) => {
                run.wheels = run.definition.capped(robot, asked);
                run.commanded = true;
                run.last_command = Instant::now();
                None
            }
            Said::Done => Some(EndReason::ControllerDone),
            Said::Fault(fault) => {
                warn!("{fault}: stopping the run");
                run.fault = Some(fault.to_string());
                Some(EndReason::Fault)
            }
        }
    }

    /// The safety margin: the layer's own, widened by how far the robot
    /// may be from its estimate (a few tenths of a millimetre with the
    /// camera watching, more the longer odometry alone carries it).
    fn margin_mm(&self) -> f64 {
        Safety::default().margin_mm + self.uncertain_mm()
    }

    /// How far the robot may be from its estimate, mm (capped: an estimate
    /// this unsure keeps the robot well away from everything mapped).
    fn uncertain_mm(&self) -> f64 {
        UNCERTAINTY_SIGMAS * self.localiser.position_sd_mm().min(MAX_UNCERTAINTY_MM)
    }

    /// Whether a followed run has come no further along its path for
    /// `HELD_BACK` (the safety layer holding it back, or something in
    /// the way), and if so where and why.
    fn held_back(&mut self, pose: Pose) -> Option<HeldBack> {
        let robot_radius = self.info.robot.radius_mm;
        let uncertain_mm = self.uncertain_mm();
        let run = self.run.as_mut()?;
        let now = Instant::now();
        if run.held || run.turning || (run.commanded && run.last_command.elapsed() <= WATCHDOG) {
            run.progress.excuse(now);
            return None;
        }
        let follower = run.follower.as_ref()?;
        let along = follower.progress_mm();
        if !(run.progress).stalled(along, HeldBack::CREEP_MM, HELD_BACK, now) {
            return None;
        }
        let arena = &self.info.arena;
        let (mut passes_mm, mut wall) = (f64::INFINITY, false);
        for &p in follower.ahead(ROOM_AHEAD_MM).iter().chain([&pose.point()]) {
            let room = run.surroundings.clearance(p) - robot_radius;
            if room < passes_mm {
                passes_mm = room;
                wall = arena.wall_clearance(p) - robot_radius <= room + 1e-9;
            }
        }
        Some(HeldBack {
            uncertain_mm,
            passes_mm: passes_mm.max(0.0),
            wall,
            margin_mm: Safety::default().margin_mm,
        })
    }

    /// Ends the run (if any) for a device fault, saying what failed.
    fn fail(&mut self, fault: &RobotError) {
        if let Some(run) = self.run.as_mut() {
            run.fault = Some(fault.to_string());
        }
        self.finish(EndReason::Fault);
    }

    /// Ends the run (if any): stops the robot and reports the summary.
    fn finish(&mut self, reason: EndReason) {
        self.halt();
        let Some(run) = self.run.take() else { return };
        let pose = self
            .last
            .as_ref()
            .map(|observed| observed.pose)
            .unwrap_or_default();
        let number = run.number;
        let summary = run.summary(
            reason,
            self.event.load(Ordering::Relaxed),
            pose,
            self.source(),
        );
        debug!(?summary, "run finished");
        let _ = self.finished.send(Finished(number, summary));
        self.publish();
    }

    /// Stops the wheels; on failure there is nothing more software can do
    /// but say so (once: an offline robot is retried, not shouted at).
    fn halt(&mut self) {
        self.sent = None;
        match self.robot.drive(&Leash::STOP) {
            Ok(()) => self.sent = Some((Leash::STOP, [0.0; 2])),
            Err(e) if self.retry.is_none() => warn!("{e}: could not stop the robot"),
            Err(_) => {}
        }
    }

    fn publish(&self) {
        let Some(Observed { reading, pose }) = &self.last else {
            return;
        };
        let message = HostMessage::Feedback(Feedback {
            event: self.event.load(Ordering::Relaxed),
            t_ms: self.since.elapsed().as_secs_f64() * 1e3,
            pose: *pose,
            source: self.source(),
            wheels: reading.wheels,
            proximity: reading.proximity.clone(),
            contact: reading.contact,
            force: self.run.as_ref().and_then(|r| r.assist).map(|a| a.force),
            limited: self.run.as_ref().is_some_and(|r| r.limited),
        });
        if self.record.active() {
            if let Some(truth) = self.truth {
                self.record.send(Recordable::Truth(truth));
            }
            self.record.send(Recordable::Sent(message.clone()));
        }
        self.feedback.send_replace(Some(message));
    }
}

/// Whether `wheels` still carry the robot forward or back, not just round.
fn still_rolling(wheels: WheelSpeeds) -> bool {
    wheels.forward_mm_s().abs() > FACE_MIN_WHEEL_MM_S
}

/// Wheel speeds that turn `robot` in place from heading `theta` towards `face`.
fn turn_towards(robot: &RobotModel, theta: f64, face: f64) -> WheelSpeeds {
    let error = wrap_angle(face - theta);
    let w = (2.0 * error).clamp(-FACE_TURN_RAD_S, FACE_TURN_RAD_S);
    let wheel = (w * robot.wheel_base_mm / 2.0)
        .abs()
        .max(FACE_MIN_WHEEL_MM_S)
        * error.signum();
    robot.clamp(WheelSpeeds {
        left_mm_s: -wheel,
        right_mm_s: wheel,
    })
}

/// The map's potential field for assisted teleoperation over `cspace`
/// (the mapped and virtual obstacles grown by the robot's body), so the
/// push depends on how far the body, not its centre, is from a wall.
pub(crate) fn map_field(cspace: &CSpace) -> MapField {
    MapField::new(cspace.grid(), MAP_FIELD_INFLUENCE_MM, MAP_FIELD_ETA)
}
