//! Recorded runs as Guest and Host speak of them: a run's entry in the
//! Host's list, its file's name, and a part of a file on the wire.
//!
//! A part is a binary WebSocket message, told from a camera frame by its
//! magic, little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | magic `VLR1` |
//! | 4..12 | offset of this part in the file (u64) |
//! | 12..20 | the file's length (u64) |
//! | 20..22 | length *n* of the file's name (u16) |
//! | 22..22+n | the file's name, UTF-8 |
//! | 22+n.. | the bytes |
//!
//! A Guest asks for each part by its offset (`download`), so a transfer is
//! paced by the Guest and resumes from wherever it stopped.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::{EndReason, ExperimentId};

const MAGIC: &[u8; 4] = b"VLR1";
const FIXED: usize = 22;
/// The most a part carries: small beside a frame, so a download never
/// holds up the camera and feedback on the same link for long.
pub const PART_BYTES: usize = 256 << 10;
/// The longest name a recording has.
const MAX_NAME: usize = 64;

/// A recording's file name: `run-<ms since 1970>-<run>.mcap` (or
/// `idle-<ms>.mcap` between runs), nothing that could reach outside the
/// recordings folder.
#[derive(
    Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(try_from = "String", into = "String")]
pub struct RecordingName(String);

#[derive(Debug, Error, PartialEq, Eq)]
pub enum RecordingNameError {
    #[error(
        "\"{0}\" is not a recording's name: names are up to {MAX_NAME} letters, digits and dashes ending in .mcap"
    )]
    Invalid(String),
}

impl RecordingName {
    /// The name of run `run` begun at `started_ms` (ms since 1970).
    pub fn of_run(started_ms: u64, run: u64) -> RecordingName {
        RecordingName(format!("run-{started_ms}-{run}.mcap"))
    }

    /// The name of the time between runs from `started_ms` on.
    pub fn between_runs(started_ms: u64) -> RecordingName {
        RecordingName(format!("idle-{started_ms}.mcap"))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl TryFrom<String> for RecordingName {
    type Error = RecordingNameError;

    fn try_from(name: String) -> Result<Self, Self::Error> {
        let stem = name.strip_suffix(".mcap").unwrap_or("");
        let fits = !stem.is_empty()
            && name.len() <= MAX_NAME
            && stem.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-');
        if fits {
            Ok(RecordingName(name))
        } else {
            Err(RecordingNameError::Invalid(name))
        }
    }
}

impl std::str::FromStr for RecordingName {
    type Err = RecordingNameError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        RecordingName::try_from(s.to_owned())
    }
}

impl From<RecordingName> for String {
    fn from(name: RecordingName) -> String {
        name.0
    }
}

impl std::fmt::Display for RecordingName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// A recorded run, as the Host lists it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RecordedRun {
    pub name: RecordingName,
    /// The run's number at its Host (0: the time between runs).
    pub run: u64,
    /// The experiment run; none for the time between runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub experiment: Option<ExperimentId>,
    /// When it began, ms since 1970 (UTC).
    pub started_ms: u64,
    /// Who drove it, when they had an account.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub user: Option<String>,
    /// How it ended; none while it runs, or when its Host stopped first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ending: Option<EndReason>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// The file's size now.
    pub bytes: u64,
}

/// What a part of a recording says about itself.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartHeader {
    pub name: RecordingName,
    pub offset: u64,
    pub total: u64,
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum PartError {
    #[error("a recording's part of {0} bytes is shorter than its header")]
    Truncated(usize),
    #[error("a binary message that is not a recording's part (no VLR1 magic)")]
    BadMagic,
    #[error("a recording's part names no recording: {0}")]
    Name(#[from] RecordingNameError),
    #[error("a recording's part of {len} bytes at {offset} goes past its file's {total}")]
    PastEnd { offset: u64, len: usize, total: u64 },
}

impl PartHeader {
    /// Whether a binary message is a recording's part (else a frame).
    pub fn is_part(bytes: &[u8]) -> bool {
        bytes.starts_with(MAGIC)
    }

    /// The header followed by `bytes`, as one binary message.
    pub fn encode(&self, bytes: &[u8]) -> Vec<u8> {
        let name = self.name.as_str().as_bytes();
        let mut out = Vec::with_capacity(FIXED + name.len() + bytes.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&self.offset.to_le_bytes());
        out.extend_from_slice(&self.total.to_le_bytes());
        out.extend_from_slice(&(name.len() as u16).to_le_bytes());
        out.extend_from_slice(name);
        out.extend_from_slice(bytes);
        out
    }

    /// Splits a part into its header and bytes.
    pub fn decode(message: &[u8]) -> Result<(PartHeader, &[u8]), PartError> {
        if message.len() < FIXED {
            return Err(PartError::Truncated(message.len()));
        }
        if !PartHeader::is_part(message) {
            return Err(PartError::BadMagic);
        }
        let u64_at = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&message[i..i + 8]);
            u64::from_le_bytes(b)
        };
        let (offset, total) = (u64_at(4), u64_at(12));
        let n = usize::from(u16::from_le_bytes([message[20], message[21]]));
        let Some(name) = message.get(FIXED..FIXED + n) else {
            return Err(PartError::Truncated(message.len()));
        };
        let name = RecordingName::try_from(String::from_utf8_lossy(name).into_owned())?;
        let bytes = &message[FIXED + n..];
        if offset.saturating_add(bytes.len() as u64) > total {
            return Err(PartError::PastEnd {
                offset,
                len: bytes.len(),
                total,
            });
        }
        Ok((
            PartHeader {
                name,
                offset,
                total,
            },
            bytes,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn parts_round_trip(
            ms in any::<u64>(), run in any::<u64>(), offset in 0u64..1 << 40,
            bytes in proptest::collection::vec(any::<u8>(), 0..512), extra in 0u64..1000,
        ) {
            let header = PartHeader {
                name: RecordingName::of_run(ms, run),
                offset,
                total: offset + bytes.len() as u64 + extra,
            };
            let wire = header.encode(&bytes);
            prop_assert!(PartHeader::is_part(&wire));
            let (back, payload) = PartHeader::decode(&wire).unwrap();
            prop_assert_eq!(back, header);
            prop_assert_eq!(payload, &bytes[..]);
        }

        #[test]
        fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..128)) {
            let _ = PartHeader::decode(&bytes);
        }
    }

    #[test]
    fn names_stay_inside_the_folder() {
        for bad in [
            "../etc/passwd.mcap",
            "a/b.mcap",
            ".mcap",
            "run.txt",
            "run 1.mcap",
        ] {
            assert!(RecordingName::try_from(bad.to_owned()).is_err(), "{bad}");
        }
        assert!(RecordingName::try_from("run-1764000000000-3.mcap".to_owned()).is_ok());
    }
}
