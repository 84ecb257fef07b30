//! The headless Guest: scripts a whole session — mount, plan a path to the
//! goal on the lab's map and define it, then execute it: the Host follows
//! the path (navigation), or a scripted operator steers along it from the
//! feedback it sees, as a person at a joystick would (teleoperation) — with
//! no window, for demos, tests and unattended runs; or watches one as an
//! observer.

use std::time::{Duration, Instant};

use serde::Serialize;
use thiserror::Error;
use vl_core::{
    ArenaPlanError, DefineKind, Definition, Drive, EndReason, ErrorCode, Experiment, ExperimentId,
    Goal, GuestMessage, HeldBack, HostMessage, ModuleHash, PathAnalysis, Point, Pose, PoseSource,
    Role, Summary,
};
use vl_report::table::{Report as _, Table, yes};

use crate::client::{ClientError, Connection, Incoming, open};
use crate::login::Login;
use crate::route::Route;
pub use crate::session::RoundTripMs;
use crate::session::{MeanMax, Pacing, Session};
use crate::settings::Settings;
use crate::tasks::TaskChoice;

/// What the scripted session does.
#[derive(Debug, Clone)]
pub struct Script {
    /// The experiment to run; the first the Host offers when absent.
    pub experiment: Option<ExperimentId>,
    /// Where to drive; the arena's suggested goal when absent.
    pub goal: Option<Goal>,
    /// The points to visit in order, for an experiment that defines them.
    pub waypoints: Vec<Point>,
    /// Who the Guest says it is.
    pub login: Login,
    /// The whole session must finish within this.
    pub timeout: Duration,
    /// Print a line of progress to stderr every second.
    pub progress: bool,
    /// How an operator's commands are paced (teleoperation).
    pub pacing: Pacing,
    /// How long an unreachable Host is tried again before giving up.
    pub connect_within: Duration,
    /// Download the run's recording into this folder once it ends.
    pub download_to: Option<std::path::PathBuf>,
    /// A saved task to run, and a name to save the run's definition as.
    pub task: TaskChoice,
    /// The definition to run as it is (a task's), instead of planning one.
    pub definition: Option<Definition>,
    /// The user's own controller (a WebAssembly module's file), if the run's.
    pub controller: Option<Vec<u8>>,
}

impl Default for Script {
    fn default() -> Self {
        Script {
            experiment: None,
            goal: None,
            waypoints: Vec::new(),
            login: Login::default(),
            timeout: Duration::from_secs(60),
            progress: false,
            pacing: Pacing::Event,
            connect_within: Duration::from_secs(10),
            download_to: None,
            task: TaskChoice::default(),
            definition: None,
            controller: None,
        }
    }
}

/// What the scripted session achieved.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ScriptReport {
    /// Whether the run ended as its experiment counts success: at its goal
    /// (or every waypoint) for one that ends there, else by time or a stop.
    pub succeeded: bool,
    pub reached_goal: bool,
    pub reason: EndReason,
    /// Why the safety layer would not let the run go on, when it would not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_back: Option<HeldBack>,
    pub events: u64,
    pub final_pose: Pose,
    pub sim_seconds: f64,
    pub distance_mm: f64,
    pub collisions: u64,
    pub frames: u64,
    /// Bytes of camera images received.
    pub video_bytes: u64,
    pub round_trip_ms: RoundTripMs,
    /// Where the pose the Host steered by came from.
    pub pose_source: PoseSource,
    /// The path the Guest planned and defined.
    pub planned: Vec<Point>,
    /// The followed path against the planned one, as the Host measured it.
    pub path: Option<PathAnalysis>,
    /// The run against the forecast of its definition.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forecast: Option<vl_core::Gap>,
    /// Commands the operator sent.
    pub commands: u64,
    /// The synchronisation the Host counted: the largest gap between a
    /// command and the feedback its Guest had seen, and the commands more
    /// than one event ahead.
    pub max_event_gap: u64,
    pub sync_violations: u64,
    /// The predicted pose against the feedback that later arrived, and the
    /// last reported pose against it (what showing feedback alone is off by).
    pub prediction_error_mm: MeanMax,
    pub stale_error_mm: MeanMax,
    /// Each command's gap as the Guest saw it, with the seconds since the
    /// run started.
    #[serde(skip)]
    pub gaps: Vec<(f64, u64)>,
    /// The run's summary as the Host sent it, and its recording downloaded.
    pub summary: Summary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub downloaded: Option<std::path::PathBuf>,
}

#[derive(Debug, Error)]
pub enum ScriptError {
    #[error(transparent)]
    Connect(#[from] ClientError),
    #[error("the Host refused to {step}: {message} ({code})")]
    Refused {
        step: &'static str,
        code: ErrorCode,
        message: String,
    },
    #[error("the connection ended while waiting to {step}: {reason}")]
    Closed { step: &'static str, reason: String },
    #[error("gave up waiting to {step} after {seconds:.0} s")]
    Timeout { step: &'static str, seconds: f64 },
    #[error("the {0} experiment's arena suggests no goal and none was given")]
    NoGoal(ExperimentId),
    #[error("the Host offers no experiment")]
    NoExperiment,
    #[error("the {0} experiment runs your own controller: give one (--controller FILE.wasm)")]
    NoController(ExperimentId),
    #[error("no path to the goal")]
    NoPath(#[from] ArenaPlanError),
    #[error("the definition, tried on the lab's twin, is {0}")]
    Forecast(String),
    #[error("the run's recording: {0}")]
    Download(#[from] crate::recordings::DownloadError),
    #[error(transparent)]
    Task(#[from] crate::tasks::TaskError),
}

impl ScriptError {
    /// Whether the user gave something wrong (a Host's address that is
    /// none, a task that is not kept): theirs to fix.
    pub fn is_bad_input(&self) -> bool {
        matches!(self, ScriptError::Connect(c) if c.is_bad_address())
            || matches!(self, ScriptError::Task(_))
    }
}

/// Runs `script` against the Host at `url`: the Host follows the planned
/// path in an experiment whose run follows one; a scripted operator steers
/// along it in one driven by stick. The one way `demo`, `guest --headless`
/// and the experiments run a Guest without a window.
pub async fn run_script(url: &str, script: &Script) -> Result<ScriptReport, ScriptError> {
    let mut script = script.clone();
    if let Some(task) = script.task.to_run()? {
        script.experiment = Some(task.experiment);
        script.definition = Some(task.definition);
    }
    let (guest, definition, goal, experiment) = started(url, &script).await?;
    // A run the Host steers (or the user's controller), or holds still,
    // is watched to its end.
    let mut report = match !experiment.takes_commands() || experiment.follows() {
        true => follow_path(guest, definition, goal, &script).await,
        false => drive_by_stick(guest, definition, goal, &script).await,
    }?;
    report.succeeded = match experiment.ends_at_goal() {
        true => report.reached_goal,
        false => matches!(report.reason, EndReason::TimeLimit | EndReason::Stopped),
    };
    Ok(report)
}

/// A Guest that waits for what it asked for.
pub(crate) struct Scripted {
    pub(crate) connection: Connection,
    pub(crate) session: Session,
    progress: bool,
    deadline: Instant,
    timeout: Duration,
    /// Until when an unreachable Host is tried again.
    connect_by: Instant,
}

impl Scripted {
    /// Takes in messages until `done` holds; an `error` from the Host, a
    /// closed connection or the deadline end the wait with a reason.
    pub(crate) async fn until(
        &mut self,
        step: &'static str,
        mut on_each: impl FnMut(&mut Session, &Connection),
        done: impl Fn(&Session) -> bool,
    ) -> Result<(), ScriptError> {
        while !done(&self.session) {
            let incoming = tokio::time::timeout_at(self.deadline.into(), self.connection.recv())
                .await
                .map_err(|_| ScriptError::Timeout {
                    step,
                    seconds: self.timeout.as_secs_f64(),
                })?;
            match incoming {
                None => {
                    return Err(ScriptError::Closed {
                        step,
                        reason: "the connection task ended".into(),
                    });
                }
                Some(Incoming::Message(message)) => match *message {
                    HostMessage::Error { code, message } => {
                        return Err(ScriptError::Refused {
                            step,
                            code,
                            message,
                        });
                    }
                    other => self.session.apply(Incoming::Message(Box::new(other))),
                },
                Some(Incoming::Unreachable { error, .. }) if Instant::now() >= self.connect_by => {
                    return Err(ScriptError::Connect(error));
                }
                Some(Incoming::Closed(reason)) => return Err(ScriptError::Closed { step, reason }),
                Some(other) => {
                    other.tell(self.progress);
                    self.session.apply(other);
                }
            }
            on_each(&mut self.session, &self.connection);
        }
        Ok(())
    }

    /// The run's report, once its summary has come; says goodbye, so the
    /// role is free for the next operator at once.
    async fn report(
        mut self,
        definition: Definition,
        script: &Script,
    ) -> Result<ScriptReport, ScriptError> {
        let summary = self.session.done.clone().expect("done");
        let downloaded = crate::recordings::download_run(
            &mut self.connection,
            script.download_to.as_deref(),
            &summary,
            (self.progress, self.deadline),
        )
        .await?;
        let report = ScriptReport {
            // Judged against the experiment by `run_script`.
            succeeded: false,
            reached_goal: summary.reached_goal,
            reason: summary.reason,
            held_back: summary.held_back,
            events: summary.events,
            final_pose: summary.final_pose,
            sim_seconds: summary.seconds,
            distance_mm: summary.distance_mm,
            collisions: summary.collisions,
            frames: self.session.frames_received,
            video_bytes: self.session.video_bytes,
            round_trip_ms: RoundTripMs::from(&self.session.round_trips),
            pose_source: summary.pose_source,
            planned: definition.path,
            path: summary.path.clone(),
            forecast: summary.forecast,
            commands: self.session.sent_event,
            max_event_gap: summary.max_event_gap,
            sync_violations: summary.sync_violations,
            prediction_error_mm: self.session.prediction_error,
            stale_error_mm: self.session.stale_error,
            gaps: std::mem::take(&mut self.session.gaps),
            summary,
            downloaded,
        };
        self.connection.close().await;
        Ok(report)
    }
}

impl ScriptReport {
    /// How the run ended, in words.
    pub fn ending(&self) -> String {
        self.summary.ending()
    }
}

/// Connects to `url` and says hello as `role`.
pub(crate) async fn welcomed(
    url: &str,
    role: Role,
    script: &Script,
) -> Result<Scripted, ScriptError> {
    let connection = open(url)?;
    connection.send(script.login.hello(role));
    let mut guest = Scripted {
        connection,
        session: Session::default(),
        progress: script.progress,
        deadline: Instant::now() + script.timeout,
        timeout: script.timeout,
        connect_by: Instant::now() + script.connect_within,
    };
    guest
        .until("say hello", |_, _| {}, |s| s.role.is_some())
        .await?;
    if role == Role::Operator && guest.session.role == Some(Role::Observer) {
        // Someone else drives: the connection watches and waits in line.
        let mut told = None;
        let progress = guest.progress;
        let tell_place = |s: &mut Session, _: &Connection| {
            let position = s.queue.map(|q| q.position);
            if progress && position.is_some() && position != told {
                told = position;
                eprintln!(
                    "someone else drives: number {} in line for control",
                    position.unwrap_or(0)
                );
            }
        };
        guest
            .until("wait in line for control", tell_place, |s| {
                s.role == Some(Role::Operator)
            })
            .await?;
    }
    Ok(guest)
}

/// Connects to `url` as operator and mounts the experiment; plans a path
/// from where the robot is seen to the goal on the lab's map, as a user does
/// on the camera view, defines it and starts the run.
async fn started(
    url: &str,
    script: &Script,
) -> Result<(Scripted, Definition, Goal, Experiment), ScriptError> {
    let mut guest = welcomed(url, Role::Operator, script).await?;
    guest.session.pacing = script.pacing;
    let ignore = |_: &mut Session, _: &Connection| {};
    let asked = match &script.experiment {
        Some(id) => id.clone(),
        None => guest
            .session
            .experiments
            .first()
            .map(|e| e.id.clone())
            .ok_or(ScriptError::NoExperiment)?,
    };
    guest.connection.send(GuestMessage::Mount {
        experiment: asked.to_string(),
    });
    // The last operator's experiment may still be mounted: wait for ours.
    let ours = |s: &Session| s.lab.as_ref().is_some_and(|l| l.experiment == asked);
    guest.until("mount", ignore, ours).await?;
    let lab = guest.session.lab.clone().expect("mounted");
    let experiment = guest
        .session
        .mounted()
        .cloned()
        .ok_or(ScriptError::NoExperiment)?;
    let task_goal = script.definition.as_ref().and_then(|d| d.goal);
    let last_waypoint = script.waypoints.last().copied().map(Goal::at);
    let goal = match (
        task_goal.or(last_waypoint).or(script.goal),
        lab.scene.arena.goal,
    ) {
        (Some(goal), _) => goal,
        (None, Some(p)) => Goal::at(p),
        (None, None) => return Err(ScriptError::NoGoal(experiment.id)),
    };
    // A lab getting ready drives the robot back to its start first: the
    // path is planned from where it will start.
    guest
        .until("see the robot at a ready lab", ignore, |s| {
            s.robot.is_some() && s.devices.is_some() && s.ready()
        })
        .await?;
    let start = guest.session.robot.as_ref().expect("seen").pose;
    let settings = Settings::default();
    let controller = match (&script.controller, experiment.runs_a_controller()) {
        (Some(file), true) => Some(sent_controller(&mut guest, file).await?),
        (None, true) => return Err(ScriptError::NoController(experiment.id)),
        (_, false) => None,
    };
    let definition = match (&script.definition, experiment.waypoint_bounds()) {
        (Some(definition), _) => definition.clone(),
        // The controller drives to the goal.
        (None, _) if controller.is_some() => Definition {
            goal: Some(goal),
            controller,
            ..Definition::default()
        },
        // Without points given, the fewest it visits along the way to the
        // goal.
        (None, Some((min, _))) => {
            let waypoints = match script.waypoints.is_empty() {
                true => Route::plan(&lab, start, goal, Vec::new(), &settings)?.along(min),
                false => script.waypoints.clone(),
            };
            let tolerance_mm = goal.tolerance_mm;
            Route::plan_through(&lab, start, &waypoints, tolerance_mm, Vec::new(), &settings)?
                .definition
        }
        // Nothing to go to: the defaults, within the experiment's numbers.
        (None, None) if !experiment.defines(DefineKind::Goal { required: false }) => {
            Definition::default()
        }
        (None, None) => Route::plan(&lab, start, goal, Vec::new(), &settings)?.definition,
    };
    if let Some(file) = script.task.keep(experiment.id.clone(), &definition)?
        && script.progress
    {
        eprintln!("saved the definition as a task: {}", file.display());
    }
    guest.connection.send(GuestMessage::Define {
        definition: definition.clone(),
    });
    guest
        .until("define the goal", ignore, |s| s.definition.is_some())
        .await?;
    if experiment.forecasts() {
        guest
            .until("be told the forecast", ignore, |s| s.forecast.is_some())
            .await?;
        let verdict = guest.session.forecast.as_ref().expect("told");
        if script.progress {
            eprintln!("{}", verdict.table());
        }
        if !verdict.passed() {
            return Err(ScriptError::Forecast(verdict.words()));
        }
    }
    guest.connection.send(GuestMessage::Start);
    guest.until("start", ignore, |s| s.running).await?;
    Ok((guest, definition, goal, experiment))
}

/// Sends the controller's `file` and waits for the Host to take it: its hash.
async fn sent_controller(guest: &mut Scripted, file: &[u8]) -> Result<ModuleHash, ScriptError> {
    let hash = ModuleHash::of(file);
    for part in crate::upload::controller_parts(file) {
        guest.connection.send(part);
    }
    guest
        .until(
            "send the controller",
            |_, _| {},
            |s| s.controller == Some(hash),
        )
        .await?;
    Ok(hash)
}

/// How long a run that ran out of time is given to report its end.
const STOP_WAIT: Duration = Duration::from_secs(5);

/// With the run started on a path to the goal, which the Host follows:
/// reports the run's end. A run that outlasts `script.timeout` is stopped
/// and reported as stopped.
async fn follow_path(
    mut guest: Scripted,
    definition: Definition,
    goal: Goal,
    script: &Script,
) -> Result<ScriptReport, ScriptError> {
    let ignore = |_: &mut Session, _: &Connection| {};

    // The Host follows the path; the Guest watches it go. No commands, so
    // no events to count: the run's time instead.
    let mut last_progress = Instant::now();
    let since = Instant::now();
    let progress = script.progress;
    let watch = move |session: &mut Session, _: &Connection| {
        let Some(robot) = &session.robot else { return };
        if progress && last_progress.elapsed() >= Duration::from_secs(1) {
            last_progress = Instant::now();
            eprintln!(
                "{:>5.1} s  pose ({:>5.0}, {:>5.0}) mm  {:>5.0} mm to go",
                since.elapsed().as_secs_f64(),
                robot.pose.x_mm,
                robot.pose.y_mm,
                robot.pose.point().distance(goal.point())
            );
        }
    };
    match guest
        .until("reach the goal", watch, |s| s.done.is_some())
        .await
    {
        // Out of time: the run is stopped, and its summary still says how it went.
        Err(ScriptError::Timeout { .. }) => {
            guest.connection.send(GuestMessage::Stop);
            guest.deadline = Instant::now() + STOP_WAIT;
            guest.until("stop", ignore, |s| s.done.is_some()).await?;
        }
        other => other?,
    }

    guest.report(definition, script).await
}

/// How close to a waypoint the operator moves on to the next, mm.
const WAYPOINT_REACHED_MM: f64 = 40.0;
/// How far apart the operator's waypoints lie along the planned path, mm.
const WAYPOINT_SPACING_MM: f64 = 80.0;
/// The operator's cruising speed, mm/s, and turn gain, 1/s.
const OPERATOR_SPEED_MM_S: f64 = 80.0;
const OPERATOR_TURN_GAIN: f64 = 3.0;
/// The shortest lag a person reacts within, s.
const REACTION_S: f64 = 0.2;
/// The share of the goal's tolerance the operator aims within before
/// letting go of the stick, so the robot's coasting keeps it inside.
const ARRIVED: f64 = 0.6;
/// Wheels slower than this, mm/s, are seen as stopped.
const STILL_MM_S: f64 = 2.0;
/// How often the operator looks and moves the stick.
const OPERATOR_TICK: Duration = Duration::from_millis(10);

/// Waypoints along `path`, about `WAYPOINT_SPACING_MM` apart, ending at its end.
fn waypoints(path: &[Point]) -> Vec<Point> {
    let mut out: Vec<Point> = Vec::new();
    let mut last = path.first().copied();
    for &p in path {
        if last.is_some_and(|l| l.distance(p) >= WAYPOINT_SPACING_MM) {
            out.push(p);
            last = Some(p);
        }
    }
    if let Some(&end) = path.last() {
        out.push(end);
    }
    out
}

/// A person's steering toward `target` from where the robot was last
/// seen: turn toward it, go forward only as far as it lies ahead, and —
/// as people do on a laggy link — no faster than the lag lets them see
/// the effect: a turn is taken out over about one lag, and the robot
/// slows so that it covers the last stretch to the goal in a few lags.
fn steer(seen: Pose, target: Point, to_goal_mm: f64, lag_s: f64) -> Drive {
    let lag = lag_s.max(REACTION_S);
    let bearing = (target.y_mm - seen.y_mm).atan2(target.x_mm - seen.x_mm);
    let error = vl_core::wrap_angle(bearing - seen.theta_rad);
    let ahead = error.cos().max(0.0);
    Drive::Velocity {
        v: (OPERATOR_SPEED_MM_S * ahead * ahead).min(0.5 * to_goal_mm / lag),
        w: (OPERATOR_TURN_GAIN.min(0.8 / lag) * error).clamp(-2.0, 2.0),
    }
}

/// With the run started on a path to the goal: drives the robot along it
/// by commands — steering toward waypoints on the path from the feedback
/// as it arrives, paced by `script.pacing` — and stops the run when the
/// feedback shows the goal reached.
async fn drive_by_stick(
    mut guest: Scripted,
    definition: Definition,
    goal: Goal,
    script: &Script,
) -> Result<ScriptReport, ScriptError> {
    let targets = waypoints(&definition.path);
    let mut next = 0;
    let mut tick = tokio::time::interval(OPERATOR_TICK);
    let mut stopping = false;
    // The first command of the stick let go, while it stays let go.
    let mut let_go: Option<u64> = None;
    let mut last_progress = Instant::now();
    loop {
        tokio::select! {
            incoming = guest.connection.recv() => match incoming {
                None => return Err(ScriptError::Closed { step: "drive", reason: "the connection task ended".into() }),
                Some(Incoming::Closed(reason)) => return Err(ScriptError::Closed { step: "drive", reason }),
                Some(other) => {
                    other.tell(script.progress);
                    guest.session.apply(other);
                }
            },
            _ = tick.tick() => {}
            () = tokio::time::sleep_until(guest.deadline.into()) => {
                if stopping {
                    return Err(ScriptError::Timeout { step: "stop", seconds: script.timeout.as_secs_f64() });
                }
                guest.connection.send(GuestMessage::Stop);
                stopping = true;
                guest.deadline = Instant::now() + STOP_WAIT;
            }
        }
        if guest.session.done.is_some() {
            break;
        }
        let Some((seen, still)) = guest.session.robot.as_ref().map(|r| {
            let w = r.wheels;
            (
                r.pose,
                w.left_mm_s.abs().max(w.right_mm_s.abs()) < STILL_MM_S,
            )
        }) else {
            continue;
        };
        while next + 1 < targets.len() && seen.point().distance(targets[next]) < WAYPOINT_REACHED_MM
        {
            next += 1;
        }
        let to_goal = seen.point().distance(goal.point());
        if stopping {
            continue;
        }
        // Seen stopped at the goal after letting go: the run is done.
        let acknowledged = guest.session.robot.as_ref().map_or(0, |r| r.event);
        if to_goal <= goal.tolerance_mm && still && let_go.is_some_and(|e| acknowledged >= e) {
            guest.connection.send(GuestMessage::Stop);
            stopping = true;
            guest.deadline = Instant::now() + STOP_WAIT;
            continue;
        }
        // Near enough: let go of the stick and wait to see it stop.
        let drive = if to_goal <= ARRIVED * goal.tolerance_mm {
            Drive::Velocity { v: 0.0, w: 0.0 }
        } else {
            let lag_s = guest.session.round_trips.last().unwrap_or(0.0) / 1e3;
            steer(seen, targets[next], to_goal, lag_s)
        };
        if let Some(command) = guest.session.next_command(drive, Instant::now()) {
            let resting = drive == Drive::Velocity { v: 0.0, w: 0.0 };
            let_go = match (resting, let_go) {
                (false, _) => None,
                (true, None) => Some(guest.session.sent_event),
                (true, kept) => kept,
            };
            guest.connection.send(command);
        }
        if script.progress && last_progress.elapsed() >= Duration::from_secs(1) {
            last_progress = Instant::now();
            eprintln!(
                "event {:>5}  pose ({:>5.0}, {:>5.0}) mm  {:>5.0} mm to go",
                guest.session.sent_event, seen.x_mm, seen.y_mm, to_goal
            );
        }
    }
    guest.report(definition, script).await
}

impl vl_report::table::Report for ScriptReport {
    fn table(&self) -> Table {
        let pose = self.final_pose;
        Table::pairs([
            ("reached goal", yes(self.reached_goal).to_owned()),
            ("end", self.ending()),
            ("events", self.events.to_string()),
            (
                "final pose",
                format!(
                    "({:.1}, {:.1}) mm, {:.1}°",
                    pose.x_mm,
                    pose.y_mm,
                    pose.theta_rad.to_degrees()
                ),
            ),
            ("lab time", format!("{:.2} s", self.sim_seconds)),
            ("distance", format!("{:.0} mm", self.distance_mm)),
            ("collisions", self.collisions.to_string()),
            ("pose from", self.pose_source.to_string()),
            (
                "path error",
                vl_core::ErrorMm::cell(self.path.as_ref().and_then(|p| p.path_error_mm)),
            ),
            (
                "estimate error",
                vl_core::ErrorMm::cell(self.path.as_ref().and_then(|p| p.estimate_error_mm)),
            ),
            (
                "frames",
                format!("{} ({:.0} kB)", self.frames, self.video_bytes as f64 / 1e3),
            ),
            ("round trip", self.round_trip_ms.cell()),
            (
                "against the forecast",
                self.forecast.map_or("–".into(), |gap| gap.to_string()),
            ),
            (
                "recording",
                self.downloaded
                    .as_ref()
                    .map_or("–".into(), |file| file.display().to_string()),
            ),
        ])
    }
}
