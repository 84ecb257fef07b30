//! The vl Guest: the user's side of the lab. `client` speaks to a Host
//! (reached over TCP or TLS by `dial`, saying who it is as `login` makes it),
//! `session` holds what the Guest knows, `route` plans paths for the Host to follow,
//! `gamepad` reads a real stick and renders the force on it,
//! `app` draws it all in a window and `headless` scripts it without one
//! (`vl-campaign` runs those scripts against a simulated Host, measured).
//! The Guest knows nothing of the Host's code: only the protocol
//! (`vl-core`) and the recordings (`vl-record`).
//!
//! In detail:
//!
//! - modules: the user's side: the connection, opened at once and connected
//!   on its own task so an unreachable Host is an event, not a failure, tried
//!   again with back-off from the first attempt and whenever an established
//!   link drops (the back-off starting afresh only once a Host welcomed it),
//!   saying hello with the operator's resume secret, giving up at once on
//!   something that answers but is no vl Host, and saying goodbye on close
//!   (`client`); `ws://` over TCP or `wss://` over TLS, trusting a pinned
//!   certificate (`#pin=`) or the public authorities (`dial`); an account,
//!   a token or no one, and the hello that says it (`login`); one `Session` state type, which forgets everything a Host
//!   told at every welcome (a Host started again begins its clocks, frames
//!   and marking anew), with its pacing (event- or time-based) and
//!   synchronisation count (`session`); the predictive display's model, the
//!   pose now from the last feedback and the commands in flight through the
//!   speed response and the watchdog, judged by later feedback (`predict`);
//!   `Route`, the one way the window and the scripted Guest plan a path, and
//!   a dragged path's bending and C-space check (`route`); the user's
//!   settings kept as TOML between sessions (`settings`); gamepads through
//!   evdev and the force → rumble/constant-force mapping (`gamepad`); the
//!   small live view of the lab's net in users' words, folded at first
//!   (`netview`); the egui window — a one-line status bar, repainting four
//!   times a second at idle and every 30 ms while something moves — with the
//!   emergency stop, the force arrows, the predictive display's ghost with a
//!   legend, the driven trail, the age of what is shown (a frame as old as
//!   its capture), Back to start and who pressed STOP, virtual obstacles
//!   drawn by dragging, the C-space overlay, path editing and the settings
//!   panel, the login form, the line for control and the slot's time left
//!   (`app`); the scripted Guests, an operator on a busy lab waiting its
//!   turn in line: the Host following a defined path,
//!   an operator steering along it from the delayed feedback, lag-aware as a
//!   person is (`headless`), and the watching observer (`watch`); a recorded
//!   run downloaded a part at a time, resumed where it stopped (`recordings`),
//!   played back through the same session and view with a slider
//!   (`replay`), and its results plotted (`results`, drawn as SVG and PNG
//!   by `plots`); definitions kept by
//!   name to be run again (`tasks`)

mod app;
mod client;
mod dial;
mod gamepad;
mod headless;
mod login;
mod netview;
pub mod plots;
mod predict;
mod recordings;
mod replay;
mod results;
mod route;
mod session;
mod settings;
mod status;
mod tasks;
mod watch;

pub use app::{
    CAMERA_VIEW, GuestApp, WindowError, display_available, run_replay_window, run_window,
};
pub use client::{ClientError, Connection, GOODBYE_WAIT, Incoming, open};
#[cfg(target_os = "linux")]
pub use gamepad::Gamepad;
pub use gamepad::{Effect, GamepadError, Pad, PadChoice, PadInput, effect};
pub use headless::{
    RoundTripMs, Script, ScriptError, ScriptReport, drive_to_goal, run_script, teleoperate,
};
pub use login::Login;
pub use predict::Predictor;
pub use recordings::{DownloadError, download};
pub use replay::{Replay, ReplayReport, replay_headless};
pub use results::Results;
pub use route::{EditRefused, Route, check_path, drag_path};
pub use session::{
    CameraFrame, DeviceStates, InLine, LinkState, MeanMax, Pacing, RoundTrips, Session, TIME_PERIOD,
};
pub use settings::{Settings, SettingsError};
pub use status::{StatusError, host_status};
pub use tasks::{Task, TaskChoice, TaskError, TaskName, Tasks};
pub use watch::{Watched, watch};
