//! Every run kept: the thesis's Experiment Database as MCAP files, one a
//! run, that Foxglove and Lichtblick open with no set-up.
//!
//! A run's file has two kinds of channel. The protocol's own messages, as
//! the Guests got them (`/feedback`, `/summary`, …: JSON, one schema a
//! kind), are what `vl guest --replay` plays back and what any numeric
//! field is plotted from. Foxglove's views of them (`/camera`, `/robot/pose`,
//! `/tf`, `/scene`, …, in Foxglove's schemas) are what its panels draw.
//!
//! The recorder (`writer`) is a thread of its own fed by a bounded queue:
//! the control loop and the camera only ever try to hand it something,
//! and what it cannot take is dropped and counted (camera frames first).
//! It closes a chunk at least once a second, so a Host killed mid-run
//! leaves a file `reader` reads (and `repair` rewrites whole) up to the
//! last second. `catalogue` keeps the folder: names, who may see which
//! run, what the retention limits let go; `export` turns a run into CSV,
//! PNGs and JSON.

mod catalogue;
mod export;
mod foxglove;
mod reader;
mod records;
mod schemas;
mod views;
mod writer;

/// The names of the files a run's recording keeps beside its messages:
/// written by `writer`, read back by `reader`.
mod attached {
    pub(crate) const DEFINITION: &str = "definition.json";
    pub(crate) const ROBOT: &str = "robot.json";
    pub(crate) const LAB: &str = "lab.json";
    pub(crate) const CONFIG: &str = "config.json";
    /// The user's controller as sent: binary, or the text format.
    pub(crate) const CONTROLLER_WASM: &str = "controller.wasm";
    pub(crate) const CONTROLLER_WAT: &str = "controller.wat";
}

pub use catalogue::now_ms;
pub use catalogue::{Catalogue, Owner, RecordSettings, Runs, data_dir, recordings_dir};
pub use export::{Exported, export};
pub use foxglove::Level;
pub use reader::{
    Message, RecordError, Recording, RecordingInfo, Repaired, Replayed, TopicCount, repair,
};
pub use records::Damage;
pub use views::{Motion, View, Views};
pub use writer::{Begin, Feed, Recordable, Stopped, now_ns, unix_ns_at};

pub use schemas::Schema;

/// A client's round trip, from the Host's pings.
#[derive(Debug, Clone, Copy, serde::Serialize, schemars::JsonSchema)]
pub struct RoundTrip {
    /// The connection, as the Host numbers them.
    pub connection: u64,
    pub ms: f64,
}

/// Each channel of a recording: one home for its topic and schema.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Topic {
    /// The protocol's messages, by kind.
    Lab,
    Definition,
    Forecast,
    Started,
    Feedback,
    State,
    Status,
    Summary,
    /// The operator's commands as the Host took them.
    Commands,
    /// Each client's round-trip time, from the Host's pings.
    RoundTrip,
    /// In simulation, where the robot truly is.
    TruePose,
    /// Foxglove's views.
    Camera,
    Annotations,
    /// The camera's intrinsics and lens, and where it stands.
    Calibration,
    CameraTransform,
    Pose,
    Transform,
    Scene,
    /// The camera-built map and the C-space, as grids.
    Map,
    CSpace,
    /// The defined path and each forecast seed's, as poses.
    Path,
    Seeds,
    /// The proximity sensors as a scan, and the robot's motion as numbers.
    Scan,
    Motion,
    Log,
}

impl Topic {
    pub fn name(self) -> &'static str {
        match self {
            Topic::Lab => "/lab",
            Topic::Definition => "/definition",
            Topic::Forecast => "/forecast",
            Topic::Started => "/started",
            Topic::Feedback => "/feedback",
            Topic::State => "/state",
            Topic::Status => "/status",
            Topic::Summary => "/summary",
            Topic::Commands => "/commands",
            Topic::RoundTrip => "/round_trip",
            Topic::TruePose => "/robot/true_pose",
            Topic::Camera => "/camera",
            Topic::Annotations => "/camera/annotations",
            Topic::Calibration => "/camera/calibration",
            Topic::CameraTransform => "/tf_static",
            Topic::Pose => "/robot/pose",
            Topic::Transform => "/tf",
            Topic::Scene => "/scene",
            Topic::Map => "/map",
            Topic::CSpace => "/cspace",
            Topic::Path => "/path",
            Topic::Seeds => "/forecast/seeds",
            Topic::Scan => "/robot/ir",
            Topic::Motion => "/robot/motion",
            Topic::Log => "/log",
        }
    }

    /// The protocol's message kinds a replay feeds back, in the order a
    /// run's messages come.
    pub const REPLAYED: [Topic; 7] = [
        Topic::Lab,
        Topic::Definition,
        Topic::Forecast,
        Topic::Started,
        Topic::Feedback,
        Topic::State,
        Topic::Summary,
    ];

    pub fn schema(self) -> Schema {
        use foxglove::Kind;
        use schemas::{heard, sent};
        match self {
            Topic::Lab => sent("vl.Mounted", "mounted", "the lab as mounted"),
            Topic::Definition => sent("vl.Defined", "defined", "the run's definition"),
            Topic::Forecast => sent(
                "vl.Forecast",
                "forecast",
                "the definition tried on the lab's twin",
            ),
            Topic::Started => sent("vl.Started", "started", "the run began"),
            Topic::Feedback => sent(
                "vl.Feedback",
                "feedback",
                "the robot, every control period it is published",
            ),
            Topic::State => sent("vl.State", "state", "the supervisor's firings and marking"),
            Topic::Status => sent("vl.Status", "status", "the lab's devices"),
            Topic::Summary => sent("vl.Done", "done", "the run's summary"),
            Topic::Commands => heard("vl.Command", "command", "an operator's command"),
            Topic::RoundTrip => schemas::schema_of::<RoundTrip>("vl.RoundTrip"),
            Topic::Motion => schemas::schema_of::<Motion>("vl.Motion"),
            Topic::TruePose | Topic::Pose => Kind::PoseInFrame.schema(),
            Topic::Path | Topic::Seeds => Kind::PosesInFrame.schema(),
            Topic::Camera => Kind::CompressedImage.schema(),
            Topic::Annotations => Kind::ImageAnnotations.schema(),
            Topic::Calibration => Kind::CameraCalibration.schema(),
            Topic::Transform | Topic::CameraTransform => Kind::FrameTransform.schema(),
            Topic::Scene => Kind::SceneUpdate.schema(),
            Topic::Map | Topic::CSpace => Kind::Grid.schema(),
            Topic::Scan => Kind::LaserScan.schema(),
            Topic::Log => Kind::Log.schema(),
        }
    }

    /// Whether a late subscriber gets this channel's newest messages at
    /// once: it changes seldom and says what the lab is.
    pub fn latched(self) -> bool {
        matches!(
            self,
            Topic::Scene
                | Topic::Map
                | Topic::CSpace
                | Topic::Calibration
                | Topic::CameraTransform
                | Topic::Path
                | Topic::Seeds
                | Topic::State
                | Topic::Status
                | Topic::Lab
                | Topic::Definition
                | Topic::Forecast
                | Topic::Started
                | Topic::Summary
        )
    }

    /// The topic a message of the protocol is kept on, if it is kept.
    pub fn of(message: &vl_core::HostMessage) -> Option<Topic> {
        use vl_core::HostMessage as M;
        Some(match message {
            M::Mounted(_) => Topic::Lab,
            M::Defined { .. } => Topic::Definition,
            M::Forecast(_) => Topic::Forecast,
            M::Started { .. } => Topic::Started,
            M::Feedback(_) => Topic::Feedback,
            M::State(_) => Topic::State,
            M::Status { .. } => Topic::Status,
            M::Done { .. } => Topic::Summary,
            _ => return None,
        })
    }
}
