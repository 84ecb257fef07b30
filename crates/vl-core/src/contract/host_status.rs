//! What an administrator sees of a running Host (`vl host status`, and
//! `GET /status` on the Host's port): its devices, who drives, who waits
//! in line, how many watch, and the runs of the day.

use serde::{Deserialize, Serialize};

use super::protocol::{DeviceState, Readiness};
use super::summary::EndReason;
use crate::ExperimentId;
use vl_report::table::{Report, Table};

/// The Host's state for its administrator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct HostStatus {
    pub robot: DeviceState,
    pub camera: DeviceState,
    /// Whether a run may start (not while the robot drives back to its start).
    pub lab: Readiness,
    pub mounted: Option<ExperimentId>,
    /// The run under way, by number.
    pub run: Option<u64>,
    pub operator: Option<Person>,
    /// What is left of the operator's slot, when slots have a length.
    pub slot_left_s: Option<f64>,
    /// Who waits for control, first in line first.
    pub queue: Vec<Person>,
    /// Clients welcomed (the operator among them).
    pub connected: u32,
    /// Runs started since midnight (UTC).
    pub runs_today: u32,
    /// The latest runs, newest last: at most [`HostStatus::RUNS_KEPT`].
    pub runs: Vec<RunRecord>,
    /// What the processor gives the control loop and the serial guard.
    #[serde(default)]
    pub priority: Priorities,
    /// Why the recorder last stopped a run's file before its end (the
    /// folder's limit, a full disk); none while every run is recorded whole.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording_stopped: Option<String>,
    /// Scores sent to the LMS, at a lab launched from one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grades: Option<GradesStatus>,
    /// The Zenoh endpoints this lab's own router opens, beyond this
    /// machine, to anyone unauthenticated (`--ros2` listening widely).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub open_to_anyone: Vec<String>,
}

/// The scores a lab sent to its LMS: posted, still being tried, given up
/// on (and why the last one was).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GradesStatus {
    pub posted: u64,
    pub sending: u64,
    pub failed: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_failure: Option<String>,
}

/// How soon the system runs a thread that wakes: what stands between a
/// busy machine and a robot told too late.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Priority {
    /// Real-time (`SCHED_FIFO` at this level): before every ordinary thread.
    RealTime { level: i32 },
    /// An ordinary thread with this (negative) nice value: ahead of others.
    Raised { nice: i32 },
    /// As every other thread: the system allowed no more.
    #[default]
    Normal,
}

impl std::fmt::Display for Priority {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Priority::RealTime { level } => write!(f, "real-time priority (SCHED_FIFO {level})"),
            Priority::Raised { nice } => write!(f, "raised priority (nice {nice})"),
            Priority::Normal => write!(f, "normal priority (the system allowed no more)"),
        }
    }
}

/// The priorities of the Host's real-time parts.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
pub struct Priorities {
    pub control: Priority,
    /// The serial guard's; none without one (a simulated robot).
    pub guard: Option<Priority>,
}

impl std::fmt::Display for Priorities {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "the control loop runs at {}", self.control)?;
        match self.guard {
            Some(guard) => write!(f, ", the serial guard at {guard}"),
            None => Ok(()),
        }
    }
}

impl HostStatus {
    /// Runs the status lists.
    pub const RUNS_KEPT: usize = 20;
}

/// Someone driving or waiting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Person {
    /// Their connection; none while their link is down (their role or
    /// place is held for them).
    pub session: Option<u64>,
    /// The account they logged in with.
    pub user: Option<String>,
}

/// One run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RunRecord {
    pub run: u64,
    pub experiment: ExperimentId,
    /// When it started, seconds since 1970 (UTC).
    pub started_unix_s: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub user: Option<String>,
    /// Why it ended; none while it goes on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended: Option<EndReason>,
}

impl std::fmt::Display for Person {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let who = self.user.as_deref().unwrap_or("anonymous");
        match self.session {
            Some(session) => write!(f, "{who} (session {session})"),
            None => write!(f, "{who} (link down, held)"),
        }
    }
}

impl Report for HostStatus {
    fn table(&self) -> Table {
        let state = |s: DeviceState| {
            match s {
                DeviceState::Online => "online",
                DeviceState::Offline => "OFFLINE",
                DeviceState::Absent => "none",
            }
            .to_owned()
        };
        let mut table = Table::pairs([
            ("robot", state(self.robot)),
            ("camera", state(self.camera)),
            ("lab", self.lab.to_string()),
            (
                "mounted",
                self.mounted
                    .as_ref()
                    .map_or("nothing".into(), ExperimentId::to_string),
            ),
            (
                "run",
                self.run
                    .map_or("none".into(), |run| format!("{run}, under way")),
            ),
            (
                "operator",
                self.operator
                    .as_ref()
                    .map_or("no one".into(), Person::to_string),
            ),
            (
                "slot left",
                match (&self.operator, self.slot_left_s) {
                    (None, _) => "-".into(),
                    (Some(_), None) => "no limit".into(),
                    (Some(_), Some(s)) => format!("{}:{:02}", s as u64 / 60, s as u64 % 60),
                },
            ),
            ("in line", self.queue.len().to_string()),
            ("connected", self.connected.to_string()),
            ("runs today", self.runs_today.to_string()),
            ("priority", self.priority.to_string()),
        ])
        .title("the Host now:");
        if let Some(why) = &self.recording_stopped {
            table = table.note(format!("recording stopped: {why}"));
        }
        if !self.open_to_anyone.is_empty() {
            table = table.note(format!(
                "WARNING: the Zenoh router on {} takes anyone on the network, unauthenticated",
                self.open_to_anyone.join(", ")
            ));
        }
        if let Some(g) = &self.grades {
            let mut grades = format!(
                "grades to the LMS: {} posted, {} being sent, {} failed",
                g.posted, g.sending, g.failed
            );
            if let Some(why) = &g.last_failure {
                grades.push_str(&format!(" (the last: {why})"));
            }
            table = table.note(grades);
        }
        for (i, person) in self.queue.iter().enumerate() {
            table = table.note(format!("in line {}: {person}", i + 1));
        }
        for r in &self.runs {
            table = table.note(format!(
                "run {} ({}) by {}: {}",
                r.run,
                r.experiment,
                r.user.as_deref().unwrap_or("anonymous"),
                r.ended.map_or("under way".into(), |e| e.to_string())
            ));
        }
        table
    }
}
