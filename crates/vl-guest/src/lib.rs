//! The vl Guest: the user's side of the lab. [`client`] speaks to a Host,
//! [`session`] holds what the Guest knows, [`app`] draws it in a window and
//! [`headless`] scripts it without one.

pub mod app;
pub mod client;
pub mod headless;
pub mod session;
