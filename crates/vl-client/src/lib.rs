//! The vl Guest without its window: everything a client of a Host does
//! that needs no display. `client` speaks to a Host (reached over TCP or
//! TLS by `dial`, saying who it is as `login` makes it), `session` holds
//! what the Guest knows, `route` plans paths for the Host to follow,
//! `headless` scripts a Guest and `watch` an observer (`vl-campaign` runs
//! those scripts against a simulated Host, measured), `recordings`
//! downloads runs, `replay` plays them back and `results` reads them for
//! plots (`plots` draws them as SVG and PNG). The window (`vl-guest`) is
//! built on this crate; so are the measurements, which must not link a
//! window toolkit. It knows nothing of the Host's code: only the protocol
//! (`vl-core`) and the recordings (`vl-record`).
//!
//! In detail:
//!
//! - modules: the connection, opened at once and connected
//!   on its own task so an unreachable Host is an event, not a failure, tried
//!   again with back-off from the first attempt and whenever an established
//!   link drops (the back-off starting afresh only once a Host welcomed it),
//!   saying hello with the operator's resume secret, giving up at once on
//!   something that answers but is no vl Host, and saying goodbye on close
//!   (`client`); `ws://` over TCP or `wss://` over TLS, trusting a pinned
//!   certificate (`#pin=`) or the public authorities (`dial`); an account,
//!   a token or no one, and the hello that says it (`login`); one `Session`
//!   state type, which forgets everything a Host told at every welcome (a
//!   Host started again begins its clocks, frames and marking anew), with
//!   its pacing (event- or time-based) and synchronisation count
//!   (`session`); the predictive display's model, the pose now from the
//!   last feedback and the commands in flight through the speed response
//!   and the watchdog, judged by later feedback (`predict`); `Route`, the
//!   one way the window and the scripted Guest plan a path, and a dragged
//!   path's bending and C-space check (`route`); the user's settings kept
//!   as TOML between sessions (`settings`); the scripted Guests, an
//!   operator on a busy lab waiting its turn in line: the Host following a
//!   defined path, an operator steering along it from the delayed
//!   feedback, lag-aware as a person is (`headless`), and the watching
//!   observer (`watch`); a recorded run downloaded a part at a time,
//!   resumed where it stopped (`recordings`), played back through the same
//!   session as a live one (`replay`), and its results read for plotting
//!   (`results`, drawn as SVG and PNG by `plots`); definitions kept by name
//!   to be run again (`tasks`); a Host's status page read as an
//!   administrator (`status`)

mod client;
mod dial;
mod headless;
mod login;
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
mod upload;
mod watch;

pub use client::{ClientError, Connection, GOODBYE_WAIT, Incoming, open};
pub use headless::{RoundTripMs, Script, ScriptError, ScriptReport, run_script};
pub use login::Login;
pub use predict::Predictor;
pub use recordings::{DownloadError, Downloading, download, downloads_dir};
pub use replay::{Replay, ReplayReport, replay_headless};
pub use results::{Results, Series};
pub use route::{EditRefused, Route, check_path, drag_path};
pub use session::{
    CameraFrame, DeviceStates, InLine, LinkState, MeanMax, Pacing, RoundTrips, Session, TIME_PERIOD,
};
pub use settings::{MARGIN_MM, MAX_SPEED_MM_S, Settings, SettingsError};
pub use status::{StatusError, host_status};
pub use tasks::{Task, TaskChoice, TaskError, TaskName, Tasks};
pub use upload::{ControllerFileError, controller_parts, read_controller};
pub use watch::{Watched, watch};
