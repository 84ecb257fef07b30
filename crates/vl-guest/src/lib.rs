//! The vl Guest's window: `app` draws the lab in egui — what `vl-client`
//! knows of it (the connection, the session, routes, replays) — and
//! `gamepad` reads a real stick and renders the force on it.
//!
//! In detail:
//!
//! - modules: gamepads through evdev and the force → rumble/constant-force
//!   mapping (`gamepad`); the small live view of the lab's net in users'
//!   words, folded at first (`netview`); the egui window — a one-line
//!   status bar, repainting four times a second at idle and every 30 ms
//!   while something moves — with the emergency stop, the force arrows,
//!   the predictive display's ghost with a legend, the driven trail, the
//!   age of what is shown (a frame as old as its capture), Back to start
//!   and who pressed STOP, virtual obstacles drawn by dragging, the C-space
//!   overlay, path editing and the settings panel, the login form, the line
//!   for control and the slot's time left, a replay's controls and its
//!   results plotted beside the camera view (`app`)

mod app;
mod gamepad;
mod netview;

pub use app::{
    CAMERA_VIEW, GuestApp, WindowError, display_available, run_replay_window, run_window,
};
#[cfg(target_os = "linux")]
pub use gamepad::Gamepad;
pub use gamepad::{Effect, GamepadError, Pad, PadChoice, PadInput, effect};
