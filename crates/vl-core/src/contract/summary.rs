//! A run's summary: how it ended and what it achieved, as the Host sends
//! it in `done` and keeps it with the run's recording.

use serde::{Deserialize, Serialize};

use crate::{PathAnalysis, Pose, PoseSource, Role};

/// Why a run ended.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::VariantArray,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum EndReason {
    GoalReached,
    Stopped,
    TimeLimit,
    OperatorLeft,
    Fault,
    /// Someone pressed the emergency stop.
    EmergencyStop,
    /// The operator sent no command for the lease time.
    OperatorSilent,
    /// The camera lost sight of the robot for longer than odometry alone
    /// may carry a run.
    RobotLost,
    /// The safety layer held the robot back for so long that the run
    /// cannot go on: `Summary::held_back` says why.
    HeldBack,
    /// The operator's slot ended and the next in line took control.
    SlotEnded,
    /// One of the lab's administrators ended the operator's turn.
    Kicked,
    /// The user's controller said it was done (`vl_step` returned 1).
    ControllerDone,
}

impl std::fmt::Display for EndReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            EndReason::GoalReached => "goal reached",
            EndReason::Stopped => "stopped",
            EndReason::TimeLimit => "time limit",
            EndReason::OperatorLeft => "operator left",
            EndReason::Fault => "fault",
            EndReason::EmergencyStop => "emergency stop",
            EndReason::OperatorSilent => "operator silent",
            EndReason::RobotLost => "the camera lost the robot",
            EndReason::HeldBack => "held back by the safety layer",
            EndReason::SlotEnded => "the operator's slot ended",
            EndReason::Kicked => "ended by the lab's administrator",
            EndReason::ControllerDone => "the controller said it was done",
        })
    }
}

/// Who or what, other than its driver, ended a run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct EndedByOther(String);

/// What a finished run achieved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Summary {
    /// The experiment the run was of (its id), as the hub mounted it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub experiment: Option<String>,
    pub reason: EndReason,
    pub reached_goal: bool,
    /// Commands executed in the run (the last event number).
    pub events: u64,
    pub final_pose: Pose,
    /// Duration of the run on the lab's clock (simulated seconds on the simulator).
    pub seconds: f64,
    /// Sum of distances driven, mm.
    pub distance_mm: f64,
    pub collisions: u64,
    /// The least room the body had to anything the Host knows of, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub closest_mm: Option<f64>,
    /// Of the forward speed commands asked for, the share the safety layer
    /// let through (1: it never had to slow the robot).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_kept: Option<f64>,
    /// Where the pose the Host steered and judged by came from.
    #[serde(default)]
    pub pose_source: PoseSource,
    /// The followed path against the planned one, for runs that had a plan
    /// or a witness of the truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<PathAnalysis>,
    /// The largest gap between a command's event and the feedback event
    /// its Guest had seen (commands that say what they had seen only).
    #[serde(default)]
    pub max_event_gap: u64,
    /// Commands sent more than one event ahead of the feedback their
    /// Guest had seen: losses of synchronisation.
    #[serde(default)]
    pub sync_violations: u64,
    /// Who pressed the emergency stop that ended the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped_by: Option<Stopper>,
    /// Why the safety layer would not let the run go on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_back: Option<HeldBack>,
    /// For a run ended by a fault: what failed, in words (the robot's line
    /// silent or garbled, which command, for how long).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fault: Option<String>,
    /// The run against the forecast of its definition.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forecast: Option<crate::Gap>,
    /// Where the Host recorded the run, when it records.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<RecordingNote>,
    /// For a definition with waypoints: how many the run visited, in order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waypoints: Option<WaypointsVisited>,
}

/// How many of its waypoints a run visited in order, of how many.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct WaypointsVisited {
    pub visited: usize,
    pub of: usize,
}

/// The file a run was recorded to, and what the recorder could not keep
/// up with (camera frames go first, so the control loop never waits).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RecordingNote {
    pub name: crate::RecordingName,
    pub dropped_frames: u64,
    /// Why the recording stopped before the run ended (the folder reached
    /// its limit, the disk is full): the file holds the run up to there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped: Option<String>,
}

impl Summary {
    /// Whether the one who drove the run ended it — the goal, the time
    /// limit, their own stop or emergency stop, the safety layer holding
    /// back what they drove — so that it may count for their grade; if
    /// not, who or what did (another's emergency stop, a fault, the robot
    /// lost, their turn taken away, a lost link).
    pub fn ended_by_driver(&self) -> Result<(), EndedByOther> {
        match (self.reason, &self.stopped_by) {
            (
                EndReason::GoalReached
                | EndReason::TimeLimit
                | EndReason::Stopped
                | EndReason::HeldBack,
                _,
            ) => Ok(()),
            (EndReason::EmergencyStop, Some(by)) if by.role == Role::Operator => Ok(()),
            (EndReason::EmergencyStop, Some(by)) => {
                Err(EndedByOther(format!("the emergency stop of {by}")))
            }
            (reason, _) => Err(EndedByOther(reason.to_string())),
        }
    }

    /// How the run ended, in words.
    pub fn ending(&self) -> String {
        match (&self.held_back, &self.fault) {
            (Some(why), _) if self.reason == EndReason::HeldBack => {
                format!("{}: {why}", self.reason)
            }
            (_, Some(what)) if self.reason == EndReason::Fault => {
                format!("{}: {what}", self.reason)
            }
            _ => self.reason.to_string(),
        }
    }
}

/// Where a run was held back, and how unsure the estimate was there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct HeldBack {
    /// How far the robot may be from its estimate (two standard
    /// deviations), mm.
    pub uncertain_mm: f64,
    /// The least room the path ahead leaves between the body and what is
    /// mapped, mm.
    pub passes_mm: f64,
    /// Whether that is a wall of the arena (else an obstacle).
    pub wall: bool,
    /// The room the safety layer keeps besides the uncertainty, mm.
    pub margin_mm: f64,
}

impl HeldBack {
    /// A run counts as held back once it comes less than this far along
    /// its path in the hold's time, mm. A held robot may so stand this much
    /// short of where the margin begins: the uncertainty explains the hold
    /// while it and the margin reach within this of the path's room.
    pub const CREEP_MM: f64 = 5.0;

    /// Whether the estimate's uncertainty, with the margin, is what keeps
    /// the robot from the room the path leaves (else something unmapped).
    pub fn by_uncertainty(&self) -> bool {
        self.uncertain_mm + self.margin_mm + Self::CREEP_MM >= self.passes_mm
    }
}

impl std::fmt::Display for HeldBack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = if self.wall { "the wall" } else { "an obstacle" };
        if self.by_uncertainty() {
            write!(
                f,
                "position uncertain by {:.0} mm where the path passes {:.0} mm from {what}: \
                 add a camera or widen the margin",
                self.uncertain_mm, self.passes_mm
            )
        } else {
            write!(
                f,
                "the robot could not move on where the path passes {:.0} mm from {what}: \
                 something the map does not show may be in the way",
                self.passes_mm
            )
        }
    }
}

/// Who pressed an emergency stop: their role and session.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Stopper {
    pub role: Role,
    pub session: u64,
}

impl std::fmt::Display for Stopper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.role {
            Role::Operator => write!(f, "the operator (session {})", self.session),
            Role::Observer => write!(f, "an observer (session {})", self.session),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::HeldBack;

    fn held(uncertain_mm: f64, passes_mm: f64) -> String {
        HeldBack {
            uncertain_mm,
            passes_mm,
            wall: false,
            margin_mm: 5.0,
        }
        .to_string()
    }

    #[test]
    fn a_robot_held_short_of_the_margin_is_held_by_its_uncertainty() {
        // A run on slipping odometry stalls a step before its margin
        // (5 mm and 19.6 mm of uncertainty) meets the 25.3 mm the path leaves.
        assert!(held(19.6, 25.3).starts_with("position uncertain by 20 mm"));
        assert!(held(2.0, 25.3).starts_with("the robot could not move on"));
    }
}
