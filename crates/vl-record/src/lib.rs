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
mod views;
mod writer;

pub use catalogue::now_ms;
pub use catalogue::{Catalogue, Owner, RecordSettings, Runs, data_dir};
pub use export::{Exported, export};
pub use foxglove::Level;
pub use reader::{
    Message, RecordError, Recording, RecordingInfo, Repaired, Replayed, TopicCount, repair,
};
pub use records::Damage;
pub use views::{View, Views};
pub use writer::{Begin, Feed, Recordable, Stopped, now_ns, unix_ns_at};

pub use foxglove::Schema;

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
    Pose,
    Transform,
    Scene,
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
            Topic::Pose => "/robot/pose",
            Topic::Transform => "/tf",
            Topic::Scene => "/scene",
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
        let plain = |name: &'static str, what: &str| Schema {
            name,
            body: serde_json::json!({
                "type": "object",
                "title": name,
                "description": format!("{what}: the message of vl's protocol v1 (docs/protocol.md), as its Guests got it"),
            }),
        };
        match self {
            Topic::Lab => plain("vl.Mounted", "the lab as mounted"),
            Topic::Definition => plain("vl.Defined", "the run's definition"),
            Topic::Forecast => plain("vl.Forecast", "the definition tried on the lab's twin"),
            Topic::Started => plain("vl.Started", "the run began"),
            Topic::Feedback => plain(
                "vl.Feedback",
                "the robot, every control period it is published",
            ),
            Topic::State => plain("vl.State", "the supervisor's firings and marking"),
            Topic::Status => plain("vl.Status", "the lab's devices"),
            Topic::Summary => plain("vl.Done", "the run's summary"),
            Topic::Commands => plain("vl.Command", "an operator's command"),
            Topic::RoundTrip => plain("vl.RoundTrip", "a client's round trip, ms"),
            Topic::TruePose | Topic::Pose => foxglove::pose_in_frame(),
            Topic::Camera => foxglove::compressed_image(),
            Topic::Annotations => foxglove::image_annotations(),
            Topic::Transform => foxglove::frame_transform(),
            Topic::Scene => foxglove::scene_update(),
            Topic::Log => foxglove::log(),
        }
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
