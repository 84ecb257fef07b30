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
//!
//! Where things are:
//!
//! - `contract/` `protocol`, `frame`, `experiment`, `definition`, `supervisor`:
//!   protocol v1's messages and codec; camera frames on the wire (36-byte
//!   header); the `Experiment`s a lab offers as their folders declare them,
//!   and the `Definition` a user gives, with its validation; the session
//!   supervisor: each experiment's controlled net as its design gives it, whose
//!   enabled transitions decide what may happen (mount, define, start, stop,
//!   command, finish, release, and the lab's own cspace_built, path_planned,
//!   field_built), telling a `NetState` (marking, enabled events, transitions
//!   fired) and followed by the Guest
//!
//! - `design/` `pipeline`, `report`, `summary`, `offered`: the labs designed
//!   by their own nets: each experiment folder (`assets/experiments/<id>/`,
//!   its `experiment.toml` declaring the experiment and naming its charts,
//!   uncontrollable events and controllers; the shared charts in
//!   `crates/vl-core/nets/`), through
//!   from-scxml → compose → the uncontrolled composition's bad interleavings
//!   per rule → controllers → the controlled net checked and its parallel
//!   places fused; the PNML, DOT and Markdown report `vl lab nets` writes;
//!   `Experiments`, those a lab offers, designed and verified
//!
//! - `model/` `robot`, `proximity`, `response_fit`, `khepera`, `camera`,
//!   `lens`, `arena` (`shape`, `material`, `map`, `load`): poses, points,
//!   wheel speeds, the robot model and differential-drive kinematics, its
//!   measured `wheel_slip` (how fast odometry grows uncertain), its
//!   `SpeedResponse` (gain, time constant, acceleration limit, dead time: the
//!   law the simulator moves by and the safety layer brakes by); the IR
//!   response and its inverse, and what a sensor reads of the map
//!   (`mapped_reading`, which the simulator adds noise to and the pose
//!   estimate compares with); fitting the response to measured steps (thesis
//!   C.2); `KheperaCommand`/`KheperaReply`, the Khepera's serial protocol for
//!   both its ends; the camera's mm↔pixel model (a homography and the lens's
//!   radial distortion k₁, k₂, fitted by DLT/SVD and then together by
//!   Levenberg–Marquardt from point pairs); the arena: shape geometry
//!   (bounds, distance, rays, `FromStr`), what obstacles are made of (IR
//!   reflectivity, colour), top-view images whose dark pixels become
//!   obstacles, and `Arena::load` (shipped by name, or a JSON file)
//!
//! - `vision/` `threshold`, `components`, `robot`, `floor`, `target`:
//!   OpenCV-compatible grey and Otsu, connected components over row runs with
//!   closed-form moments, Hu invariants and holes, the robot's pose from its
//!   marker; `inspect` runs the pipeline, `bench` times it; `floor::look`,
//!   what one frame says (the robot's pose, the floor's occupancy without the
//!   robot, the map as an `Arena`, the robot painted out); the dot target a
//!   camera is calibrated from, each dot's centre weighted by its darkness
//!
//! - `navigation/` `cspace`, `nf1`, `spline`, `plan`, `follow`, `localise`,
//!   `analysis`, `svg`, `bench`: occupancy grids grown by a disc (the exact
//!   distance transform, taken only as far as the disc reaches, rows split
//!   over two threads) or per-θ polygon footprint; the NF1 wavefront (held
//!   front by front) and its descent; chord-length cubic splines; planning
//!   with validation and exact clearance (each pose looks a few cells around
//!   it; the whole-map transform only for a path far from everything), and
//!   `plan_route`, the one way a path to a goal is planned for a robot in its
//!   arena (its samples pushed clear of obstacles as far as the room allows);
//!   the path follower (`Follower::for_definition`); the pose estimate,
//!   odometry (its uncertainty grown by each wheel's slip) and camera
//!   sightings folded in at their frames' exposure, or with no camera the
//!   proximity readings against the map, in an extended Kalman filter
//!   (`Localiser`); path analysis, followed against planned (`PathRecorder`);
//!   the plan and a run as SVG; the planning benchmark (each stage, and the
//!   whole plan timed as one job)
//!
//! - `controller`: a user's own wheel controller as interface version 1
//!   sees it (its observation and command) and the `Controller` trait a
//!   sandbox (`vl-sandbox`) implements
//!
//! - `safety`: the safety layer every wheel command passes on the Host:
//!   `Surroundings` (exact signed clearance to walls, obstacles, virtual
//!   obstacles, whose boxes are worked out once per run), `Safety::guard`
//!   (the command as a `Leash`, run out — the last leash (`Told`) goes on
//!   until it reaches the wheels, then each wheel's trapezoid to the end of
//!   its reach; keep the turn, give up forward speed until the robot, left
//!   to itself, stops clear; else stop at once; past a face only moving out
//!   passes); `model/leash`: the leash and the position controller that
//!   ends it
//!
//! - `images`: `load_image`/`decode_image`, the one way an image from
//!   outside (arena maps, `vl vision`/`vl plan` inputs, camera frames at the
//!   Guest) is decoded: its size is checked against 8192 px a side and 256 MB
//!   before anything is allocated
//!
//! - `named`: `Named`: kinds users name by a fixed id (experiment, robot,
//!   link profile, connectivity) — one id list, one parser, serde as the id;
//!   the binary's `named()` value parser lists the ids in `--help`

mod contract;
mod controller;
mod design;
mod images;
mod model;
mod named;
mod navigation;
mod safety;
mod syntax;
mod teleop;
mod vision;

/// Results printed for people (vl-petri's, the crate every other builds on).
/// For `named_by_id!` in other crates, and the protocol's schemas.
pub use schemars;

pub use contract::access::{AccessEvent, AccessNet, AccessNetError, AccessRefused, Seat};
pub use contract::cells::{CellInfo, CellName, CellStatus, GatewayStatus, NotACellName};
pub use contract::definition::{Definition, DefinitionError, Goal, LOOKAHEAD_MM, Visited};
pub use contract::experiment::{
    BadExperimentId, DefineKind, Experiment, ExperimentError, ExperimentId, Reach, RunComponent,
    RunPlan, Setting, Success,
};
pub use contract::fingerprint::Fingerprint;
pub use contract::forecast::{
    Closest, Forecast, ForecastLimits, ForecastRefusal, ForecastVerdict, Gap, Nearest, SeedRun,
    Spread,
};
pub use contract::frame::{FrameError, FrameHeader, ImageFormat, MAX_FRAME_BYTES};
pub use contract::host_status::{
    GradesStatus, HostStatus, Person, Priorities, Priority, RunRecord,
};
pub use contract::legend::Mark;
pub use contract::protocol::{
    DecodeError, DeviceState, Drive, ErrorCode, Feedback, GuestMessage, HostMessage, LabScene,
    MAX_TEXT_BYTES, MountedLab, PROTOCOL_VERSION, Readiness, Role, Secret, WATCHDOG, Wire,
};
pub use contract::recording::{
    PART_BYTES, PartError, PartHeader, RecordedRun, RecordingName, RecordingNameError,
};
pub use contract::rubric::{Grade, GradeLine, Measured, Rubric, RubricError};
pub use contract::summary::{
    EndReason, EndedByOther, HeldBack, RecordingNote, Stopper, Summary, WaypointsVisited,
};
pub use contract::supervisor::{Action, Fired, NetState, NotAllowed, Supervisor, SupervisorError};
pub use contract::transport::Io;
pub use controller::{
    ABI_VERSION, Answer, COMMAND_WORDS, Controller, ControllerFault, MAX_MODULE_BYTES, ModuleHash,
    OBSERVATION_WORDS, Observation, STEP_PERIOD_S,
};
pub use design::{
    CheckReport, Declared, DesignError, Designed, Experiments, FolderCheck, Interleaving,
    LabDesign, LabRow, NetsReport, Offered, Rule, RuleVerdict, UnknownExperiment, design,
};
pub use images::{ImageError, MAX_IMAGE_SIDE, decode_image, load_image};
pub use model::arena::{
    Arena, ArenaError, Hit, MapImageError, Material, Obstacle, Shape, ShapeError,
};
pub use model::camera::{Calibration, CameraModel, CameraModelError, PointPair, Reprojection};
pub use model::homography::{CalibrationError, Homography};
pub use model::khepera::{
    CommandError, KheperaCommand, KheperaReply, LedAction, MalformedReply, MotorMode, MotorStatus,
};
pub use model::leash::{Leash, PositionControl, WheelMove};
pub use model::lens::{Distortion, LensError};
pub use model::pinhole::Pinhole;
pub use model::proximity::{MAX_READING, ir_distance, ir_reading, mapped_reading};
pub use model::response_fit::{Fit, FitError, Step as ResponseStep, fit_response};
pub use model::robot::{
    KHEPERA_WHEEL_SLIP, MAX_PROFILE_ACCEL, MAX_PULSES_PER_PERIOD, Point, Pose, RobotKind,
    RobotModel, RobotModelError, SensorMount, SpeedResponse, WheelSpeeds, wrap_angle,
};
pub use named::{Named, UnknownName};
pub use navigation::analysis::{
    ErrorMm, PathAnalysis, PathRecorder, PoseSource, distance_to_polyline, nearest_rank,
};
pub use navigation::bench::{PlanBench, PlanBenchError, bench as bench_planning};
pub use navigation::cspace::{CSpace, Footprint};
pub use navigation::distance::FAR;
pub use navigation::follow::{Follower, Following, PLAN_MARGIN_MM, Steer};
pub use navigation::grid::{CSpaceError, Grid};
pub use navigation::localise::{Fold, Localiser, Uncertainty};
pub use navigation::nf1::{CSpaceCell, Nf1};
pub use navigation::plan::{
    ARENA_CELL_MM, ArenaPlanError, NoPath, PathEnd, Plan, Smoothing, clearance, disc_cspace, plan,
    plan_route, plan_route_through, plan_route_with_margin,
};
pub use navigation::report::{GridInfo, PlanReport};
pub use navigation::svg::{plan_svg, run_svg};
pub use safety::{Guarded, Safety, Situation, Surroundings, Told};
pub use syntax::{ImageSize, SyntaxError, duration, duration_or_none, listen_address};
pub use teleop::{Assisted, Joystick, MapField, Teleop, Vector, predict};
pub use vision::{
    Centroid, Component, Connectivity, DotTarget, Look, Mask, RobotPose, Scene, TargetError,
    Threshold, ThresholdError, VisionBench, arena_of, bench as bench_vision, binarise,
    changed_cells, components, grey, inspect, is_robot, label, look, otsu, robot_pose,
};
