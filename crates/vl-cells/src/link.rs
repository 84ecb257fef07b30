//! A link: one Guest of the gateway at one cell. The gateway has checked
//! who they are; the cell's hub takes them as one of its own clients.

use serde::{Deserialize, Serialize};
use vl_core::{ErrorCode, GuestMessage, Role, Summary};

use vl_host::Admitted;

/// The gateway's side of a link.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub(crate) enum LinkUp {
    /// A hello the gateway's gate let through.
    Hello {
        admitted: Admitted,
        protocol: u32,
        role: Role,
        resume: Option<String>,
    },
    /// Anything else the Guest said.
    Message { message: GuestMessage },
    /// The Guest left (meaning to, or its link dropped).
    Leave { meant: bool },
}

/// The cell's side of a link.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub(crate) enum LinkDown {
    /// A protocol v1 message for the Guest, as JSON text.
    Send { text: String },
    /// The Guest was welcomed: its cell's feedback and frames are for it.
    Welcomed,
    /// The cell ends the link, saying why.
    End { code: ErrorCode, why: String },
    /// A run the Guest drove ended (the gateway grades it as them).
    RunEnded { summary: Box<Summary> },
}

impl LinkUp {
    pub(crate) fn encode(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }
}

impl LinkDown {
    pub(crate) fn encode(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }
}
