//! What the cells (and the gateway's own tasks on Zenoh) tell the front.

use tokio_tungstenite::tungstenite::Utf8Bytes;
use vl_core::{CellInfo, CellName, HostMessage};

use crate::link::LinkDown;

/// What the cells tell the front.
pub(super) enum Event {
    /// A cell's liveliness token came: it is up.
    Up(CellName),
    /// Its token went: the cell died, or its link did.
    Gone(CellName),
    Info(CellInfo),
    /// A message the cell tells its observers.
    Told(CellName, Utf8Bytes),
    /// What a late observer of the cell is told now.
    CaughtUp(CellName, Vec<HostMessage>),
    /// A link's cell said something to its Guest: the Guest, the link's
    /// number, what was said.
    Down(u64, u64, LinkDown),
}
