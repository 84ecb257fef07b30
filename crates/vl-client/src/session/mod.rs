//! What the Guest knows of its session: one state type that the desktop app
//! draws and the headless client scripts against, updated only by what
//! arrives from the Host.

use std::collections::VecDeque;

use std::time::{Duration, Instant};

use image::RgbaImage;
use vl_core::{
    Action, Definition, DeviceState, Drive, ErrorCode, Experiment, Experiments, Feedback,
    FrameHeader, GuestMessage, HostMessage, ImageFormat, MountedLab, Pose, Readiness, Role,
    Summary, Supervisor,
};

use crate::client::Incoming;

mod figures;
mod steps;
use crate::predict::Predictor;
pub use figures::{MeanMax, RoundTripMs, RoundTrips};

/// Errors kept for display; older ones are dropped.
const ERRORS_KEPT: usize = 8;
/// Commands' gaps kept per run, for a plot of synchronisation over time.
const GAPS_KEPT: usize = 100_000;

/// Whether the lab's devices answer, as the Host last said.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceStates {
    pub robot: DeviceState,
    pub camera: DeviceState,
    /// Whether a run may start, or the robot is driving back to its start.
    pub lab: Readiness,
}

/// The latest camera image, decoded.
#[derive(Debug, Clone)]
pub struct CameraFrame {
    pub header: FrameHeader,
    pub image: RgbaImage,
}

/// How the Guest paces its commands (thesis §3.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// Command s + 1 only once feedback for s has come back: the reference
    /// is the event, so Guest and Host stay within one event of each other.
    Event,
    /// A command every [`TIME_PERIOD`], whatever has come back: the
    /// reference is time, as in classic teleoperation.
    Time,
}

impl vl_core::Named for Pacing {
    const KIND: &'static str = "pacing";
    const ALL: &'static [Self] = &[Pacing::Event, Pacing::Time];

    fn id(self) -> &'static str {
        match self {
            Pacing::Event => "event",
            Pacing::Time => "time",
        }
    }
}

vl_core::named_by_id!(Pacing);

/// The period of time-based control: the Host's feedback period.
pub const TIME_PERIOD: Duration = Duration::from_millis(20);

/// Where the session stands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkState {
    Connecting,
    /// The Host has not answered yet: trying again.
    Unreachable {
        attempt: u32,
        reason: String,
    },
    Open,
    /// The link dropped; the connection is being made again.
    Reconnecting {
        attempt: u32,
        reason: String,
    },
    Closed(String),
}

/// Everything the Guest knows of its session.
#[derive(Debug, Clone)]
pub struct Session {
    pub link: LinkState,
    /// The account the Host welcomed this Guest as, if it logged in.
    pub user: Option<String>,
    pub role: Option<Role>,
    pub session_id: Option<u64>,
    pub experiments: Vec<Experiment>,
    pub lab: Option<MountedLab>,
    pub definition: Option<Definition>,
    /// The definition tried on the lab's twin, once the Host has.
    pub forecast: Option<vl_core::ForecastVerdict>,
    /// The controller of ours the Host took, by its hash.
    pub controller: Option<vl_core::ModuleHash>,
    /// How many forecasts the Host has told: a new one is told by the count.
    pub forecasts: u64,
    pub running: bool,
    pub robot: Option<Feedback>,
    /// The newest camera image shown, decoded (see [`Session::decode_frame`]).
    pub frame: Option<CameraFrame>,
    /// The newest image received, still encoded: only the one shown is
    /// decoded, however many arrive between two looks.
    newest_frame: Option<(FrameHeader, Vec<u8>)>,
    pub frames_received: u64,
    /// Bytes of camera images received (the video the link carried).
    pub video_bytes: u64,
    pub round_trips: RoundTrips,
    /// What the Host refused since the last thing that went through.
    pub errors: VecDeque<(ErrorCode, String)>,
    /// The recorded runs the Host last listed for this Guest.
    pub recordings: Option<Vec<vl_core::RecordedRun>>,
    /// The last run's summary.
    pub done: Option<Summary>,
    /// Event number of the last command sent in this run.
    pub sent_event: u64,
    /// A run was under way when the link dropped: the Host may give it back.
    interrupted: bool,
    pub devices: Option<DeviceStates>,
    /// How commands are paced.
    pub pacing: Pacing,
    /// When the last command left.
    last_sent: Option<Instant>,
    /// The largest gap between a command sent and the feedback seen, and
    /// how many commands went more than one event ahead, in this run.
    pub max_event_gap: u64,
    pub sync_violations: u64,
    /// Each command's gap, with the seconds since the run started.
    pub gaps: Vec<(f64, u64)>,
    run_started: Option<Instant>,
    /// Where the robot is now, by the feedback and the commands since.
    pub predictor: Predictor,
    /// This run's prediction error (the ghost shown at a moment against the
    /// feedback that later told where the robot was at that moment) and,
    /// beside it, the error of the last reported pose shown then.
    pub prediction_error: MeanMax,
    pub stale_error: MeanMax,
    /// When the newest feedback and frame arrived.
    pub feedback_at: Option<Instant>,
    pub frame_at: Option<Instant>,
    /// The Host's supervisor nets, run here from the firings it tells, so
    /// controls are offered exactly when their transitions are enabled.
    pub nets: Supervisor,
    /// Whether the last state the Host told matched the nets run here.
    pub nets_agree: bool,
    /// The last state the Host told: what its net enables when this Guest
    /// has no net of the mounted experiment (a folder it does not ship).
    pub told: Option<vl_core::NetState>,
    /// How many welcomes this Guest has had: each is a new connection,
    /// perhaps to a new Host, and starts what is shown afresh.
    pub welcomes: u64,
    /// How many mounts this Guest has seen: each (the same experiment
    /// mounted again for a new operator too) starts the lab afresh.
    pub mounts: u64,
    /// The lab's floor, robot and camera, as the welcome told them: enough
    /// to draw the robot before anything is mounted (see [`Session::scene`]).
    pub floor: Option<vl_core::LabScene>,
    /// The lab's last run that ended, as the Host last said.
    pub last_run: Option<vl_core::RunRecord>,
    /// Why this Guest's control was taken (its slot ended, an
    /// administrator ended it), until it asks again.
    pub control_ended: Option<vl_core::EndReason>,
    /// How many wait in line for control, as the Host last said.
    pub waiting: u32,
    /// Where this Guest stands in the line for control, when it is in it.
    pub queue: Option<InLine>,
    /// When the operator's slot ends, for an operator whose slots have a length.
    pub slot_ends: Option<Instant>,
}

/// A place in the line for control.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InLine {
    /// 1: next.
    pub position: u32,
    pub length: u32,
    /// When control comes at the latest, when slots have a length.
    pub by: Option<Instant>,
}

impl Default for Session {
    fn default() -> Self {
        Session {
            link: LinkState::Connecting,
            recordings: None,
            role: None,
            user: None,
            session_id: None,
            experiments: Vec::new(),
            lab: None,
            controller: None,
            definition: None,
            forecast: None,
            forecasts: 0,
            running: false,
            robot: None,
            frame: None,
            newest_frame: None,
            frames_received: 0,
            video_bytes: 0,
            round_trips: RoundTrips::default(),
            errors: VecDeque::new(),
            done: None,
            sent_event: 0,
            interrupted: false,
            devices: None,
            pacing: Pacing::Event,
            last_sent: None,
            max_event_gap: 0,
            sync_violations: 0,
            gaps: Vec::new(),
            run_started: None,
            predictor: Predictor::default(),
            prediction_error: MeanMax::default(),
            stale_error: MeanMax::default(),
            feedback_at: None,
            frame_at: None,
            nets: Supervisor::new(Experiments::shipped().nets())
                .expect("the shipped nets are built in and tested"),
            nets_agree: true,
            told: None,
            queue: None,
            slot_ends: None,
            welcomes: 0,
            mounts: 0,
            floor: None,
            last_run: None,
            control_ended: None,
            waiting: 0,
        }
    }
}

impl Session {
    /// Takes in one thing that arrived from the Host.
    pub fn apply(&mut self, incoming: Incoming) {
        match incoming {
            Incoming::Message(message) => self.apply_message(*message),
            Incoming::Frame(header, bytes) => self.apply_frame(header, bytes),
            // Downloads take their parts from the connection themselves.
            Incoming::Part(..) => {}
            Incoming::RoundTrip(ms) => {
                self.round_trips.push(ms);
                self.predictor.round_trip(ms);
            }
            Incoming::Unreachable { error, attempt, .. } => {
                self.link = LinkState::Unreachable {
                    attempt,
                    reason: error.to_string(),
                };
                self.running = false;
            }
            Incoming::Reconnecting {
                attempt, reason, ..
            } => {
                // Nothing goes out until the Host says the run is ours again.
                self.link = LinkState::Reconnecting { attempt, reason };
                self.interrupted |= self.running;
                self.running = false;
            }
            Incoming::Closed(reason) => {
                self.link = LinkState::Closed(reason);
                self.running = false;
            }
        }
    }

    fn apply_message(&mut self, message: HostMessage) {
        match message {
            HostMessage::Welcome {
                session,
                role,
                experiments,
                user,
                scene,
                ..
            } => {
                self.welcomed(session, role, experiments, user);
                self.floor = scene.map(|s| *s);
            }
            HostMessage::Error { code, message } => {
                if self.errors.len() == ERRORS_KEPT {
                    self.errors.pop_front();
                }
                self.errors.push_back((code, message));
            }
            HostMessage::Mounted(lab) => {
                self.lab = Some(*lab);
                self.mounts += 1;
                self.definition = None;
                self.forecast = None;
                self.done = None;
                self.errors.clear();
            }
            HostMessage::Defined { definition } => {
                self.definition = Some(definition);
                self.forecast = None;
                self.errors.clear();
            }
            HostMessage::Forecast(verdict) => self.foreseen(*verdict),
            HostMessage::ControllerTaken { sha256, .. } => self.controller = Some(sha256),
            HostMessage::State(state) => {
                self.nets_agree = self.nets.follow(&state);
                self.told = Some(*state);
                // A run asked to stop takes no more commands, though its
                // `done` is still to come.
                if !self.net_allows(Action::Command) {
                    self.running = false;
                }
            }
            // A run given back to an operator whose link dropped goes on,
            // and so does its record.
            HostMessage::Started { event } if self.interrupted => {
                self.interrupted = false;
                self.running = true;
                self.sent_event = event;
                self.last_sent = None;
                self.predictor.start();
            }
            HostMessage::Started { event } => self.started(event),
            HostMessage::Feedback(feedback) => self.feedback(feedback),
            HostMessage::Done { summary } => {
                self.interrupted = false;
                self.running = false;
                self.done = Some(*summary);
            }
            HostMessage::Status {
                robot,
                camera,
                lab,
                last_run,
            } => {
                self.devices = Some(DeviceStates { robot, camera, lab });
                self.last_run = last_run;
            }
            HostMessage::Queue {
                position,
                length,
                wait_s,
            } => {
                self.waiting = length;
                self.queue = position.map(|position| InLine {
                    position,
                    length,
                    by: wait_s.map(|s| Instant::now() + Duration::from_secs_f64(s.clamp(0.0, 1e6))),
                });
            }
            HostMessage::Role {
                role,
                slot_s,
                ended,
                ..
            } => {
                self.role = Some(role);
                self.queue = None;
                self.control_ended = ended.filter(|_| role == Role::Observer);
                self.slot_ends = slot_s
                    .filter(|_| role == Role::Operator)
                    .map(|s| Instant::now() + Duration::from_secs_f64(s.clamp(0.0, 1e6)));
            }
            HostMessage::Recordings { runs } => self.recordings = Some(runs),
            // Pings and bye are the connection's; `vl guest` plans itself.
            HostMessage::Planned { .. }
            | HostMessage::Ping { .. }
            | HostMessage::Pong { .. }
            | HostMessage::Bye => {}
        }
    }

    /// The Host let this Guest in: what an earlier Host said is forgotten.
    fn welcomed(
        &mut self,
        session: u64,
        role: Role,
        experiments: Vec<Experiment>,
        user: Option<String>,
    ) {
        self.forget_the_host();
        self.welcomes += 1;
        self.link = LinkState::Open;
        self.session_id = Some(session);
        self.role = Some(role);
        self.user = user;
        self.experiments = experiments;
    }

    /// The Host tried the definition on the lab's twin.
    fn foreseen(&mut self, verdict: vl_core::ForecastVerdict) {
        self.forecast = Some(verdict);
        self.forecasts += 1;
    }

    /// A new run began at `event`: its record starts afresh.
    fn started(&mut self, event: u64) {
        self.errors.clear();
        self.running = true;
        self.done = None;
        self.sent_event = event;
        self.last_sent = None;
        self.max_event_gap = 0;
        self.sync_violations = 0;
        self.gaps.clear();
        self.run_started = Some(Instant::now());
        self.prediction_error = MeanMax::default();
        self.stale_error = MeanMax::default();
        self.predictor.start();
    }

    /// The robot as the newest feedback reports it; the prediction is
    /// judged against it.
    fn feedback(&mut self, robot: Feedback) {
        // Feedback can only move forward in time; an older one is stale.
        if self.robot.as_ref().is_some_and(|r| r.t_ms > robot.t_ms) {
            return;
        }
        let now = Instant::now();
        if self.running
            && let Some((ghost, reported)) = self.predictor.judge(robot.pose, now)
        {
            self.prediction_error.add(ghost);
            self.stale_error.add(reported);
        }
        self.predictor
            .feedback(robot.event, robot.pose, robot.wheels, now);
        if let Some(lab) = &self.lab {
            self.predictor.remember(&lab.scene.robot, now);
        }
        self.feedback_at = Some(now);
        self.robot = Some(robot);
    }

    /// Forgets everything a Host told: a welcome opens a new connection,
    /// perhaps to a Host started again whose clocks, frame numbers and
    /// marking begin anew, so nothing from before may be shown as current.
    /// A run the link dropped during keeps its record, in case the Host
    /// gives it back.
    fn forget_the_host(&mut self) {
        let fresh = Session::default();
        self.lab = None;
        self.definition = None;
        self.forecast = None;
        self.running = false;
        self.robot = None;
        self.frame = None;
        self.newest_frame = None;
        self.errors.clear();
        self.done = None;
        self.devices = None;
        self.predictor = fresh.predictor;
        self.feedback_at = None;
        self.frame_at = None;
        self.nets = fresh.nets;
        self.nets_agree = true;
        self.told = None;
    }

    fn apply_frame(&mut self, header: FrameHeader, bytes: Vec<u8>) {
        self.video_bytes += bytes.len() as u64;
        let newest = self
            .newest_frame
            .as_ref()
            .map(|(h, _)| h.seq)
            .or(self.frame.as_ref().map(|f| f.header.seq));
        if newest.is_some_and(|seq| seq >= header.seq) {
            return;
        }
        self.frames_received += 1;
        self.frame_at = Some(Instant::now());
        self.newest_frame = Some((header, bytes));
    }

    /// Decodes the newest image received, if it is not shown yet: a window
    /// calls this before it draws; a scripted Guest never needs to.
    pub fn decode_frame(&mut self) {
        let Some((header, bytes)) = self.newest_frame.take() else {
            return;
        };
        let format = match header.format {
            ImageFormat::Jpeg => image::ImageFormat::Jpeg,
            ImageFormat::Png => image::ImageFormat::Png,
        };
        match vl_core::decode_image(&bytes, Some(format)) {
            Ok(decoded) => {
                self.frame = Some(CameraFrame {
                    header,
                    image: decoded.to_rgba8(),
                });
            }
            Err(e) => tracing::warn!("frame {} does not decode: {e}", header.seq),
        }
    }

    /// The next command, if the pacing lets one go at `now`. Under
    /// event-based control command s + 1 goes out only once feedback for
    /// command s has come back, so Guest and Host never drift more than one
    /// event apart whatever the delay; under time-based control one goes
    /// every period.
    pub fn next_command(&mut self, drive: Drive, now: Instant) -> Option<GuestMessage> {
        let seen = self.robot.as_ref().map_or(0, |r| r.event);
        if !self.running {
            return None;
        }
        let due = match self.pacing {
            Pacing::Event => seen >= self.sent_event,
            Pacing::Time => self
                .last_sent
                .is_none_or(|at| now.saturating_duration_since(at) >= TIME_PERIOD),
        };
        if !due {
            return None;
        }
        self.sent_event += 1;
        self.last_sent = Some(now);
        let gap = self.sent_event.saturating_sub(seen);
        self.max_event_gap = self.max_event_gap.max(gap);
        self.sync_violations += u64::from(gap > 1);
        if self.gaps.len() < GAPS_KEPT {
            let since = self
                .run_started
                .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
            self.gaps.push((since, gap));
        }
        if let Some(lab) = &self.lab {
            self.predictor
                .sent(self.sent_event, drive.wheels(&lab.scene.robot), now);
        }
        Some(GuestMessage::Command {
            event: self.sent_event,
            seen: Some(seen),
            drive,
        })
    }

    /// Where the robot is predicted to be now, when a lab is mounted and
    /// feedback has come.
    pub fn predicted(&self, now: Instant) -> Option<Pose> {
        let lab = self.lab.as_ref()?;
        self.predictor.predict(&lab.scene.robot, now)
    }

    /// What to draw the lab with: the mounted lab's scene, else the one
    /// the welcome told.
    pub fn scene(&self) -> Option<&vl_core::LabScene> {
        self.lab.as_ref().map(|l| &l.scene).or(self.floor.as_ref())
    }

    /// Whether the run under way, or the next, follows its path on the Host.
    pub fn host_follows(&self) -> bool {
        match (&self.lab, &self.definition) {
            (Some(_), Some(definition)) => {
                definition.host_follows(self.mounted().is_some_and(Experiment::follows))
            }
            _ => false,
        }
    }

    /// The mounted experiment, as the Host's welcome declared it.
    pub fn mounted(&self) -> Option<&Experiment> {
        let id = &self.lab.as_ref()?.experiment;
        self.experiments.iter().find(|e| e.id == *id)
    }

    /// Whether this Guest may drive.
    pub fn is_operator(&self) -> bool {
        self.role == Some(Role::Operator)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{PoseSource, WheelSpeeds};

    fn feedback(event: u64, t_ms: f64) -> Incoming {
        Incoming::Message(Box::new(HostMessage::Feedback(Feedback {
            event,
            t_ms,
            pose: Pose::default(),
            wheels: WheelSpeeds::default(),
            proximity: vec![0; 8],
            contact: false,
            force: None,
            limited: false,
            source: PoseSource::Camera,
        })))
    }

    #[test]
    fn commands_wait_for_their_feedback() {
        let mut s = Session::default();
        let drive = Drive::Velocity { v: 100.0, w: 0.0 };
        assert_eq!(
            s.next_command(drive, Instant::now()),
            None,
            "no run, no command"
        );
        s.apply(Incoming::Message(Box::new(HostMessage::Started {
            event: 0,
        })));
        assert!(matches!(
            s.next_command(drive, Instant::now()),
            Some(GuestMessage::Command { event: 1, .. })
        ));
        assert_eq!(
            s.next_command(drive, Instant::now()),
            None,
            "command 1 not yet acknowledged"
        );
        s.apply(feedback(1, 10.0));
        assert!(matches!(
            s.next_command(drive, Instant::now()),
            Some(GuestMessage::Command { event: 2, .. })
        ));
    }

    #[test]
    fn stale_feedback_is_ignored() {
        let mut s = Session::default();
        s.apply(feedback(3, 50.0));
        s.apply(feedback(2, 40.0));
        assert_eq!(s.robot.as_ref().unwrap().event, 3);
    }

    #[test]
    fn quantiles_by_nearest_rank() {
        let mut r = RoundTrips::default();
        for ms in 1..=100 {
            r.push(f64::from(ms));
        }
        assert_eq!(r.quantile(0.5), Some(50.0));
        assert_eq!(r.quantile(0.99), Some(99.0));
        assert_eq!(RoundTrips::default().quantile(0.5), None);
    }
}
