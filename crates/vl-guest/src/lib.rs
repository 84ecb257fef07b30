//! The vl Guest: the user's side of the lab. `client` speaks to a Host,
//! `session` holds what the Guest knows, `route` plans paths for the Host to follow,
//! `gamepad` reads a real stick and renders the force on it,
//! `app` draws it all in a window and `headless` scripts it without one;
//! `experiment` runs the lab's experiments on a simulated Host, measured.

mod app;
mod client;
pub mod experiment;
mod gamepad;
mod headless;
mod netview;
mod predict;
mod route;
mod session;
mod settings;

pub use app::{CAMERA_VIEW, GuestApp, WindowError, run_window};
pub use client::{ClientError, Connection, Incoming, open};
pub use gamepad::{Effect, Pad, PadInput, effect};
#[cfg(target_os = "linux")]
pub use gamepad::{Gamepad, GamepadError};
pub use headless::{
    Report, RoundTripMs, Script, ScriptError, Watched, drive_to_goal, run_script, teleoperate,
    watch,
};
pub use predict::Predictor;
pub use route::{EditRefused, Route, check_path, drag_path};
pub use session::{
    CameraFrame, ControlMode, Devices, Link, RobotState, RoundTrips, Session, Spread, TIME_PERIOD,
};
pub use settings::{Settings, SettingsError};
