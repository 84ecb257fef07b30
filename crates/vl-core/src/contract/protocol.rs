//! Protocol v1: the messages Guest and Host exchange over the Media.
//!
//! Each WebSocket text message is one JSON object whose `"type"` field names
//! the message in snake_case; camera images travel as binary messages (see
//! [`FrameHeader`](crate::FrameHeader)). `docs/protocol.md` shows one example of each message.
//! Every message that reports the lab's state carries the event number or
//! time it refers to, so a receiver can always tell stale from fresh.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::{
    Arena, CameraModel, Definition, Experiment, ExperimentId, NetState, Pose, PoseSource,
    RobotModel, Summary, WheelSpeeds,
};

/// The protocol version a `hello` must name.
pub const PROTOCOL_VERSION: u32 = 1;

/// The largest text message either side accepts.
pub const MAX_TEXT_BYTES: usize = 1 << 20;

/// A robot an operator drives stops by itself when no command has come for
/// this long: the Host's watchdog, which the Guest's prediction expects.
pub const WATCHDOG: std::time::Duration = std::time::Duration::from_millis(500);

/// A password on the wire: a string in JSON, never shown by `Debug`, so
/// no log line can hold one.
#[derive(Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(transparent)]
pub struct Secret(pub String);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(…)")
    }
}

/// Who a connection speaks for: one operator drives, observers watch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Operator,
    Observer,
}

impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Role::Operator => "operator",
            Role::Observer => "observer",
        })
    }
}

/// How a command asks the robot to move.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Drive {
    /// Wheel speeds, mm/s.
    Wheels { left: f64, right: f64 },
    /// Linear speed mm/s and turn rate rad/s.
    Velocity { v: f64, w: f64 },
}

impl From<WheelSpeeds> for Drive {
    fn from(wheels: WheelSpeeds) -> Drive {
        Drive::Wheels {
            left: wheels.left_mm_s,
            right: wheels.right_mm_s,
        }
    }
}

impl Drive {
    /// The wheel speeds this asks of `robot`, within its limits.
    pub fn wheels(&self, robot: &RobotModel) -> WheelSpeeds {
        match *self {
            Drive::Wheels { left, right } => robot.clamp(WheelSpeeds {
                left_mm_s: left,
                right_mm_s: right,
            }),
            Drive::Velocity { v, w } => robot.wheels_for(v, w),
        }
    }

    /// What a ROS Twist asks (`linear.x` m/s, `angular.z` rad/s), as
    /// Foxglove's Teleop panel and ROS 2's `/cmd_vel` send it; none for a
    /// speed that is no finite number.
    pub fn from_twist(linear_m_s: f64, angular_rad_s: f64) -> Option<Drive> {
        let drive = Drive::Velocity {
            v: linear_m_s * 1000.0,
            w: angular_rad_s,
        };
        drive.is_finite().then_some(drive)
    }

    pub fn is_finite(&self) -> bool {
        match *self {
            Drive::Wheels { left, right } => left.is_finite() && right.is_finite(),
            Drive::Velocity { v, w } => v.is_finite() && w.is_finite(),
        }
    }
}

/// Whether the lab is ready for a run, as remote labs reset their
/// equipment between users.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Readiness {
    #[default]
    Ready,
    /// The robot is driving back to the lab's start pose.
    GettingReady,
}

impl std::fmt::Display for Readiness {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Readiness::Ready => "ready",
            Readiness::GettingReady => "getting ready: the robot drives back to its start pose",
        })
    }
}

/// The robot's state after executing command `event`, at Host time `t_ms`
/// since the session began: what the Host sends every control period and
/// what the Guest shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Feedback {
    pub event: u64,
    pub t_ms: f64,
    pub pose: Pose,
    pub wheels: WheelSpeeds,
    pub proximity: Vec<u16>,
    pub contact: bool,
    /// Force to render on a haptic joystick, when the experiment has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<[f64; 2]>,
    /// The Host is holding the robot back from what was asked: the safety
    /// layer, or in an assisted run the obstacles' push.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub limited: bool,
    /// Whether `pose` rests on a recent camera sighting or on odometry alone.
    #[serde(default)]
    pub source: PoseSource,
}

/// Machine-readable reason in an `error` message.
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
pub enum ErrorCode {
    /// Not JSON, not an object, or a field of the wrong shape.
    BadMessage,
    UnknownType,
    TooLarge,
    ProtocolMismatch,
    /// Something other than `hello` arrived before `hello`.
    HelloFirst,
    Unauthorized,
    OperatorTaken,
    NotOperator,
    UnknownExperiment,
    InvalidDefinition,
    /// The definition, tried on the lab's twin, breaks the lab's limits.
    ForecastRefused,
    /// The session supervisor does not allow this action now.
    NotAllowedNow,
    /// A command whose event number is not the next one.
    StaleCommand,
    /// A stage (handshake, hello, pings, the operator's lease) took too long.
    Timeout,
    /// The robot's link is down: no run can start until it is back.
    RobotOffline,
    /// The client did not read what the Host sent fast enough.
    SlowReader,
    /// Too many failed logins from this address or for this account: wait.
    TooManyAttempts,
    /// Every place to watch from is taken; the rest are kept for people
    /// who may drive.
    LabFull,
    /// No recording of that name that this Guest may see.
    UnknownRecording,
    /// At a gateway: no cell is up, or none of the name asked for.
    NoCell,
    /// At a gateway: the cell this Guest was on stopped answering (its
    /// machine died or its cable came out); its run is over.
    CellLost,
}

/// As on the wire: `unknown_experiment`.
impl std::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let id = serde_json::to_value(self).expect("codes serialise");
        f.write_str(id.as_str().expect("codes serialise as strings"))
    }
}

/// Whether a device of the lab answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DeviceState {
    Online,
    Offline,
    /// The lab has none (a lab without a camera).
    Absent,
}

/// Messages the Guest sends. Each travels as `"type"`: its variant's name
/// in snake case, as serde writes it and `kind()` and `TYPES` list it.
#[derive(
    Debug,
    Clone,
    PartialEq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    strum::VariantNames,
    schemars::JsonSchema,
)]
#[serde(tag = "type", rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum GuestMessage {
    Hello {
        protocol: u32,
        role: Role,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        token: Option<String>,
        /// The `resume` of an operator's earlier welcome: within the Host's
        /// grace period after its link dropped, the role and the run are
        /// theirs again.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        resume: Option<String>,
        /// An account's name, with its `password`, at a lab with accounts.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        user: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        password: Option<Secret>,
        /// The session an LMS launch opened (the launched page's
        /// `vl-session`): the person the LMS vouched for, no password.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        session: Option<Secret>,
    },
    /// `t` is the sender's clock, ms; the peer echoes it in `pong`.
    Ping {
        t: f64,
    },
    Pong {
        t: f64,
    },
    /// The experiment's id. A name the Host does not offer is answered
    /// `unknown_experiment` with the ones it does, so it travels as text.
    Mount {
        experiment: String,
    },
    Define {
        #[serde(flatten)]
        definition: Definition,
    },
    /// Part of the operator's own controller (a WebAssembly module of at
    /// most 2 MiB, binary or text): the file's bytes from `offset`, in
    /// base64, of `total` bytes in all. Parts come in order, each within a
    /// message's size; the first (offset 0) starts the file afresh. The
    /// Host checks the whole file and answers `controller_taken`; a
    /// definition then names it by its hash.
    Controller {
        offset: u64,
        total: u64,
        data: String,
    },
    Start,
    Stop,
    /// Drive the robot back to the lab's start pose, as the Host does by
    /// itself after every run; the operator's, between runs.
    Reset,
    /// Stop the robot now and end the run, from anyone welcomed, observers
    /// too; nothing moves until the operator starts a new run.
    EmergencyStop,
    /// Drive command number `event` (1, 2, …) of the current run. `seen`
    /// is the newest feedback's event the Guest had when it sent it: the
    /// Host counts `event − seen` as the run's synchronisation (thesis §3.5:
    /// event-based control keeps it at most 1 whatever the delay).
    Command {
        event: u64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        seen: Option<u64>,
        #[serde(flatten)]
        drive: Drive,
    },
    /// Send a camera frame now, from anyone welcomed: a Host that sends
    /// frames only when the scene changes answers with the next one.
    RequestFrame,
    /// An observer asks for control: it joins the line for the operator's
    /// role, and gets it when its turn comes.
    Queue,
    /// Leaves the line.
    LeaveQueue,
    /// From one of the lab's administrators: ends the turn of the Guest
    /// with this `session` (its run stops and it watches) or its place in line.
    Kick {
        session: u64,
    },
    /// Lists the recorded runs this Guest may see (`recordings`).
    Recordings,
    /// Asks for the part of a recording from `offset` on; the answer is
    /// a binary part (see `contract::recording`).
    Download {
        name: crate::RecordingName,
        #[serde(default)]
        offset: u64,
    },
    /// Plans a path to `goal` on the Host's map of the mounted lab, from
    /// where the robot stands (through `through` first, in order, for an
    /// experiment that visits waypoints), for a Guest that does not plan
    /// itself (the web page): answered `planned` to it alone, defining
    /// nothing.
    Plan {
        goal: crate::Point,
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        through: Vec<crate::Point>,
    },
    Bye,
}

/// The lab as mounted: what the Guest needs to show and plan on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct MountedLab {
    pub experiment: ExperimentId,
    #[serde(flatten)]
    pub scene: LabScene,
}

/// What a Guest needs to draw the lab, mounted or not: told at the welcome
/// too, so the robot is drawn on the floor before anything is mounted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct LabScene {
    /// The floor and its obstacles: as the camera sees them when the lab
    /// has one, else as configured.
    pub arena: Arena,
    pub robot: RobotModel,
    pub camera: CameraModel,
}

/// Messages the Host sends, named on the wire as the Guest's are.
#[derive(
    Debug,
    Clone,
    PartialEq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    strum::VariantNames,
    schemars::JsonSchema,
)]
#[serde(tag = "type", rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum HostMessage {
    Welcome {
        session: u64,
        role: Role,
        experiments: Vec<Experiment>,
        /// For an operator: the secret to say hello with after a dropped
        /// link, to get the role and the running experiment back.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        resume: Option<String>,
        /// The account the Guest logged in as.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        user: Option<String>,
        /// The lab's floor, robot and camera, to draw before a mount.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        scene: Option<Box<LabScene>>,
    },
    Error {
        code: ErrorCode,
        message: String,
    },
    Ping {
        t: f64,
    },
    Pong {
        t: f64,
    },
    /// Where this Guest stands in the line for control: 1 is next; none
    /// once it is out of the line. `wait_s` is the longest it may wait
    /// when the operator's slots have a length.
    Queue {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        position: Option<u32>,
        length: u32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wait_s: Option<f64>,
    },
    /// This Guest's role changed: control granted (with the secret to come
    /// back with after a dropped link, and the slot's length) or ended.
    Role {
        role: Role,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        resume: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        slot_s: Option<f64>,
        /// Why control ended, when it was taken (`slot_ended`, `kicked`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ended: Option<crate::EndReason>,
    },
    Mounted(Box<MountedLab>),
    /// The operator's controller arrived whole and passed its checks: a
    /// definition may name it by `sha256`.
    ControllerTaken {
        sha256: crate::ModuleHash,
        bytes: u64,
    },
    Defined {
        #[serde(flatten)]
        definition: Definition,
    },
    /// The definition, tried on the lab's twin: a run may start only when
    /// its verdict passed (navigation).
    Forecast(Box<crate::ForecastVerdict>),
    /// A run began; commands count from `event` + 1.
    Started {
        event: u64,
    },
    /// The robot's state after executing command `event`.
    Feedback(Feedback),
    Done {
        summary: Box<Summary>,
    },
    /// The supervisor's net: sent on welcome and whenever a firing changes
    /// its marking.
    State(Box<NetState>),
    /// The lab's devices: sent on welcome and whenever one changes.
    Status {
        robot: DeviceState,
        camera: DeviceState,
        /// Whether a run may start: not while the robot drives back to
        /// the start pose after the last one.
        #[serde(default)]
        lab: Readiness,
        /// The last run that ended, so someone who joins later knows how
        /// the lab has been used; none before the first.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        last_run: Option<crate::RunRecord>,
    },
    /// The recorded runs this Guest may see, newest first.
    Recordings {
        runs: Vec<crate::RecordedRun>,
    },
    /// A path to `goal` from where the robot stood, planned on the lab's
    /// map for the Guest that asked (`plan`).
    Planned {
        goal: crate::Point,
        path: Vec<crate::Point>,
    },
    Bye,
}

/// Why a text message could not be decoded.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum DecodeError {
    #[error("message of {len} bytes is over the {max}-byte limit")]
    TooLarge { len: usize, max: usize },
    #[error("not valid JSON: {0}")]
    NotJson(String),
    #[error("a message must be a JSON object")]
    NotAnObject,
    #[error("message has no string \"type\" field")]
    MissingType,
    #[error("unknown message type \"{0}\"")]
    UnknownType(String),
    #[error("bad \"{kind}\" message: {detail}")]
    Invalid { kind: String, detail: String },
}

impl DecodeError {
    /// The code an `error` reply carries for this failure.
    pub fn code(&self) -> ErrorCode {
        match self {
            DecodeError::TooLarge { .. } => ErrorCode::TooLarge,
            DecodeError::UnknownType(_) => ErrorCode::UnknownType,
            _ => ErrorCode::BadMessage,
        }
    }
}

/// A message family that travels as JSON text frames.
pub trait Wire: Serialize + DeserializeOwned {
    /// The `"type"` values this family knows.
    const TYPES: &'static [&'static str];

    /// The JSON text of this message.
    fn encode(&self) -> String {
        // Every field is a plain number, string, list or map: serialising cannot fail.
        serde_json::to_string(self).expect("protocol messages serialise")
    }

    /// Parses one text frame, telling apart every way it can be wrong.
    fn decode(text: &str) -> Result<Self, DecodeError> {
        if text.len() > MAX_TEXT_BYTES {
            return Err(DecodeError::TooLarge {
                len: text.len(),
                max: MAX_TEXT_BYTES,
            });
        }
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| DecodeError::NotJson(e.to_string()))?;
        let kind = value
            .as_object()
            .ok_or(DecodeError::NotAnObject)?
            .get("type")
            .ok_or(DecodeError::MissingType)?
            .as_str()
            .ok_or(DecodeError::MissingType)?
            .to_owned();
        if !Self::TYPES.contains(&kind.as_str()) {
            return Err(DecodeError::UnknownType(kind));
        }
        serde_json::from_value(value).map_err(|e| DecodeError::Invalid {
            kind,
            detail: e.to_string(),
        })
    }
}

impl GuestMessage {
    /// The `"type"` this message travels as.
    pub fn kind(&self) -> &'static str {
        self.into()
    }
}

impl HostMessage {
    /// A refusal: what was refused (`code`) and why, in words.
    pub fn error(code: ErrorCode, message: impl Into<String>) -> HostMessage {
        HostMessage::Error {
            code,
            message: message.into(),
        }
    }
}

impl Wire for GuestMessage {
    const TYPES: &'static [&'static str] = <GuestMessage as strum::VariantNames>::VARIANTS;
}

impl Wire for HostMessage {
    const TYPES: &'static [&'static str] = <HostMessage as strum::VariantNames>::VARIANTS;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names `kind()` and `TYPES` give are the ones serde writes.
    #[test]
    fn message_names_are_serdes() {
        for message in [
            GuestMessage::EmergencyStop,
            GuestMessage::RequestFrame,
            GuestMessage::Start,
            GuestMessage::Queue,
            GuestMessage::LeaveQueue,
            GuestMessage::Recordings,
            GuestMessage::Bye,
        ] {
            let wire: serde_json::Value = serde_json::from_str(&message.encode()).unwrap();
            assert_eq!(wire["type"], message.kind());
            assert!(GuestMessage::TYPES.contains(&message.kind()));
        }
        assert_eq!(GuestMessage::TYPES.len(), 19);
        assert!(HostMessage::TYPES.contains(&"feedback") && HostMessage::TYPES.len() == 18);
        assert!(GuestMessage::TYPES.contains(&"controller"));
        assert!(HostMessage::TYPES.contains(&"controller_taken"));
        assert!(GuestMessage::TYPES.contains(&"plan") && HostMessage::TYPES.contains(&"planned"));
        assert!(GuestMessage::TYPES.contains(&"download") && HostMessage::TYPES.contains(&"done"));
        assert!(GuestMessage::TYPES.contains(&"leave_queue"));
        assert!(HostMessage::TYPES.contains(&"forecast"));
    }

    #[test]
    fn commands_take_wheels_or_velocities() {
        let wheels = GuestMessage::decode(r#"{"type":"command","event":3,"left":10,"right":-5}"#);
        assert_eq!(
            wheels,
            Ok(GuestMessage::Command {
                event: 3,
                seen: None,
                drive: Drive::Wheels {
                    left: 10.0,
                    right: -5.0
                }
            })
        );
        let velocity = GuestMessage::decode(r#"{"type":"command","event":4,"v":100,"w":0.5}"#);
        assert_eq!(
            velocity,
            Ok(GuestMessage::Command {
                event: 4,
                seen: None,
                drive: Drive::Velocity { v: 100.0, w: 0.5 }
            })
        );
    }

    #[test]
    fn every_way_of_being_wrong_is_named() {
        use DecodeError::*;
        assert!(matches!(GuestMessage::decode("hello?"), Err(NotJson(_))));
        assert_eq!(GuestMessage::decode("[1,2]"), Err(NotAnObject));
        assert_eq!(GuestMessage::decode(r#"{"t":1}"#), Err(MissingType));
        assert_eq!(GuestMessage::decode(r#"{"type":7}"#), Err(MissingType));
        assert_eq!(
            GuestMessage::decode(r#"{"type":"welcome"}"#),
            Err(UnknownType("welcome".into()))
        );
        assert!(matches!(
            GuestMessage::decode(r#"{"type":"command","event":"x","left":1,"right":1}"#),
            Err(Invalid { kind, .. }) if kind == "command"
        ));
        let big = format!(
            r#"{{"type":"ping","pad":"{}"}}"#,
            "x".repeat(MAX_TEXT_BYTES)
        );
        assert!(matches!(GuestMessage::decode(&big), Err(TooLarge { .. })));
    }
}
