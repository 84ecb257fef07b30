//! What the vl Guest and Host share, and the lab's algorithms both run.
//!
//! - the contract between them: protocol v1's messages, camera frames,
//!   experiments and their definitions, the session supervisor running the
//!   labs' controlled nets;
//! - the labs' nets designed from their statecharts (`design`);
//! - the lab's models: the robot and its Khepera protocol, the arena, the
//!   camera;
//! - vision on the overhead camera's frames;
//! - navigation: C-space, NF1, splines, path following;
//! - teleoperation: potential fields, force feedback, prediction;
//! - the safety layer every wheel command passes on the Host.
//!
//! Modules are private; what other crates use is re-exported here.

mod contract;
mod design;
mod images;
mod model;
mod named;
mod navigation;
mod safety;
mod syntax;
pub mod table;
mod teleop;
mod vision;

pub use contract::experiment::{
    Definition, DefinitionError, Experiment, ExperimentInfo, Goal, LOOKAHEAD_MM,
};
pub use contract::frame::{FrameError, FrameHeader, ImageFormat, MAX_FRAME_BYTES};
pub use contract::protocol::{
    DecodeError, DeviceState, Drive, EndReason, ErrorCode, GuestMessage, HeldBack, HostMessage,
    MAX_TEXT_BYTES, MountedLab, PROTOCOL_VERSION, Readiness, Role, Stopper, Summary, WATCHDOG,
    Wire, ending,
};
pub use contract::session::{Action, Fired, NetState, NotAllowed, Supervisor, SupervisorError};
pub use design::{DesignError, Designed, Interleaving, LabDesign, Rule, design};
pub use images::{ImageError, MAX_IMAGE_SIDE, decode_image, load_image};
pub use model::arena::{
    Arena, ArenaError, Hit, MapImageError, Material, Obstacle, Shape, ShapeError,
};
pub use model::camera::{Calibration, CameraModel, CameraModelError, Reprojection};
pub use model::homography::{CalibrationError, Homography};
pub use model::khepera::{
    CommandError, KheperaCommand, KheperaReply, LedAction, MalformedReply, MotorMode, MotorStatus,
};
pub use model::lens::{Distortion, LensError};
pub use model::proximity::{MAX_READING, ir_distance, ir_reading, mapped_reading};
pub use model::response_fit::{Fit, FitError, Step as ResponseStep, fit_response};
pub use model::robot::{
    KHEPERA_WHEEL_SLIP, MAX_PULSES_PER_PERIOD, Point, Pose, RobotKind, RobotModel, RobotModelError,
    SensorMount, SpeedResponse, WheelSpeeds, wrap_angle,
};
pub use named::{Named, UnknownName};
pub use navigation::analysis::{
    ErrorMm, PathAnalysis, PathRecorder, PoseSource, distance_to_polyline, nearest_rank,
};
pub use navigation::bench::{PlanBench, PlanBenchError, bench as bench_planning};
pub use navigation::cspace::{CSpace, Footprint};
pub use navigation::distance::FAR;
pub use navigation::follow::{Follower, Following, Steer};
pub use navigation::grid::{CSpaceError, Grid};
pub use navigation::localise::{Fold, Localiser, Uncertainty};
pub use navigation::nf1::{Cell, Nf1};
pub use navigation::plan::{
    ARENA_CELL_MM, ArenaPlanError, NoPath, PathEnd, Plan, Smoothing, clearance, disc_cspace, plan,
    plan_route, plan_route_with_margin,
};
pub use navigation::svg::{plan_svg, run_svg};
pub use safety::{Guarded, Safety, Situation, Surroundings};
pub use syntax::SyntaxError;
pub use teleop::{Assisted, Joystick, MapField, Teleop, Vector, predict};
pub use vision::{
    Centroid, Component, Connectivity, DotTarget, Look, Mask, RobotPose, Scene, Threshold,
    ThresholdError, VisionBench, arena_of, bench as bench_vision, binarise, changed_cells,
    components, grey, inspect, is_robot, label, look, otsu, robot_pose,
};
