//! The headless Guest: scripts a whole session — mount, plan a path to the
//! goal on the lab's map and define it, then execute it under event-based
//! control, steering along the path — with no window, for demos, tests and
//! unattended runs.

use std::time::{Duration, Instant};

use serde::Serialize;
use thiserror::Error;
use vl_core::experiment::{Definition, Goal};
use vl_core::follow::{Command, Follower, Following, PLAN_MARGIN_MM};
use vl_core::plan::{ArenaPlanError, plan_in_arena};
use vl_core::protocol::{
    Drive, EndReason, ErrorCode, GuestMessage, HostMessage, PROTOCOL_VERSION, Role,
};
use vl_core::robot::{Pose, WheelSpeeds};

use crate::client::{ClientError, Connection, Incoming, connect};
use crate::session::Session;

/// What the scripted session does.
#[derive(Debug, Clone)]
pub struct Script {
    pub experiment: String,
    /// Where to drive; the arena's suggested goal when absent.
    pub goal: Option<Goal>,
    pub token: Option<String>,
    /// The whole session must finish within this.
    pub timeout: Duration,
    pub following: Following,
    /// Print a line of progress to stderr every second.
    pub progress: bool,
}

impl Default for Script {
    fn default() -> Self {
        Script {
            experiment: "navigation".into(),
            goal: None,
            token: None,
            timeout: Duration::from_secs(60),
            following: Following::default(),
            progress: false,
        }
    }
}

/// Percentiles of the round-trip time, ms.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct RoundTripMs {
    pub p50: f64,
    pub p99: f64,
}

/// What the scripted session achieved.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Report {
    pub reached_goal: bool,
    pub reason: EndReason,
    pub events: u64,
    pub final_pose: Pose,
    pub sim_seconds: f64,
    pub distance_mm: f64,
    pub collisions: u64,
    pub frames: u64,
    pub round_trip_ms: RoundTripMs,
}

#[derive(Debug, Error)]
pub enum ScriptError {
    #[error(transparent)]
    Connect(#[from] ClientError),
    #[error("the Host refused to {step}: {message} ({code:?})")]
    Refused {
        step: &'static str,
        code: ErrorCode,
        message: String,
    },
    #[error("the connection ended while waiting to {step}: {reason}")]
    Closed { step: &'static str, reason: String },
    #[error("gave up waiting to {step} after {seconds:.0} s")]
    Timeout { step: &'static str, seconds: f64 },
    #[error("experiment \"{0}\" suggests no goal and none was given")]
    NoGoal(String),
    #[error("no path to the goal: {0}")]
    NoPath(#[from] ArenaPlanError),
}

/// A Guest that waits for what it asked for.
struct Scripted {
    connection: Connection,
    session: Session,
    deadline: Instant,
    timeout: Duration,
}

impl Scripted {
    /// Takes in messages until `done` holds; an `error` from the Host, a
    /// closed connection or the deadline end the wait with a reason.
    async fn until(
        &mut self,
        step: &'static str,
        mut on_each: impl FnMut(&mut Session, &Connection),
        done: impl Fn(&Session) -> bool,
    ) -> Result<(), ScriptError> {
        while !done(&self.session) {
            let incoming =
                tokio::time::timeout_at(self.deadline.into(), self.connection.incoming.recv())
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
                Some(Incoming::Closed(reason)) => return Err(ScriptError::Closed { step, reason }),
                Some(other) => self.session.apply(other),
            }
            on_each(&mut self.session, &self.connection);
        }
        Ok(())
    }
}

/// Connects to `url` as operator and drives the robot to the goal.
pub async fn drive_to_goal(url: &str, script: &Script) -> Result<Report, ScriptError> {
    let connection = connect(url).await?;
    let mut guest = Scripted {
        connection,
        session: Session::default(),
        deadline: Instant::now() + script.timeout,
        timeout: script.timeout,
    };
    let ignore = |_: &mut Session, _: &Connection| {};
    guest.connection.send(GuestMessage::Hello {
        protocol: PROTOCOL_VERSION,
        role: Role::Operator,
        token: script.token.clone(),
    });
    guest
        .until("say hello", ignore, |s| s.role.is_some())
        .await?;

    guest.connection.send(GuestMessage::Mount {
        experiment: script.experiment.clone(),
    });
    guest.until("mount", ignore, |s| s.lab.is_some()).await?;
    let lab = guest.session.lab.clone().expect("mounted");

    let goal = match (script.goal, lab.arena.goal) {
        (Some(goal), _) => goal,
        (None, Some(p)) => Goal {
            x_mm: p.x_mm,
            y_mm: p.y_mm,
            tolerance_mm: 15.0,
        },
        (None, None) => return Err(ScriptError::NoGoal(script.experiment.clone())),
    };
    // Plan from where the robot is, as a user does on the camera view.
    guest
        .until("see the robot", ignore, |s| s.robot.is_some())
        .await?;
    let start = guest.session.robot.as_ref().expect("seen").pose;
    let plan = plan_in_arena(
        &lab.arena,
        &[],
        lab.robot.radius_mm,
        PLAN_MARGIN_MM,
        start,
        goal.point(),
    )?;
    let path: Vec<_> = plan.points();
    let mut follower = Follower::new(
        path.clone(),
        Following {
            tolerance_mm: goal.tolerance_mm / 2.0,
            ..script.following
        },
    )
    .expect("a plan has samples");
    guest.connection.send(GuestMessage::Define {
        definition: Definition {
            goal: Some(goal),
            path,
            ..Definition::default()
        },
    });
    guest
        .until("define the goal", ignore, |s| s.definition.is_some())
        .await?;

    guest.connection.send(GuestMessage::Start);
    guest.until("start", ignore, |s| s.running).await?;

    let mut last_progress = Instant::now();
    let progress = script.progress;
    let steer = move |session: &mut Session, connection: &Connection| {
        let Some(robot) = &session.robot else { return };
        let wheels = match follower.step(&lab.robot, robot.pose, &robot.proximity) {
            Command::Drive(wheels) => wheels,
            Command::Arrived => WheelSpeeds::default(),
        };
        if progress && last_progress.elapsed() >= Duration::from_secs(1) {
            last_progress = Instant::now();
            eprintln!(
                "event {:>5}  pose ({:>5.0}, {:>5.0}) mm  {:>5.0} mm to go",
                robot.event,
                robot.pose.x_mm,
                robot.pose.y_mm,
                robot.pose.point().distance(goal.point())
            );
        }
        let drive = Drive::Wheels {
            left: wheels.left_mm_s,
            right: wheels.right_mm_s,
        };
        if let Some(command) = session.next_command(drive) {
            connection.send(command);
        }
    };
    guest
        .until("reach the goal", steer, |s| s.done.is_some())
        .await?;

    let summary = guest.session.done.clone().expect("done");
    let rtt = &guest.session.round_trips;
    guest.connection.send(GuestMessage::Bye);
    Ok(Report {
        reached_goal: summary.reached_goal,
        reason: summary.reason,
        events: summary.events,
        final_pose: summary.final_pose,
        sim_seconds: summary.seconds,
        distance_mm: summary.distance_mm,
        collisions: summary.collisions,
        frames: guest.session.frames_received,
        round_trip_ms: RoundTripMs {
            p50: rtt.quantile(0.5).unwrap_or(f64::NAN),
            p99: rtt.quantile(0.99).unwrap_or(f64::NAN),
        },
    })
}
