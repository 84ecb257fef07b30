//! Many lab cells behind one gateway: a cell's name, what each cell tells
//! the gateway of itself, and the gateway's status built from that.

use serde::{Deserialize, Serialize};

use super::experiment::ExperimentId;
use super::host_status::Person;
use super::protocol::Readiness;

/// A cell's name: a Zenoh key chunk (`vl/cells/NAME`) and a path
/// (`/cells/NAME`), so 1–32 of `a-z`, `0-9`, `-` and `_`.
#[derive(
    Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(try_from = "String", into = "String")]
pub struct CellName(String);

/// Why a text is no cell's name.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("{0:?} is no cell name: use 1 to 32 of a-z, 0-9, '-' and '_'")]
pub struct NotACellName(pub String);

impl CellName {
    pub const MAX_LEN: usize = 32;

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl TryFrom<String> for CellName {
    type Error = NotACellName;

    fn try_from(name: String) -> Result<CellName, NotACellName> {
        let fits = (1..=CellName::MAX_LEN).contains(&name.len())
            && name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-' || b == b'_');
        if fits {
            Ok(CellName(name))
        } else {
            Err(NotACellName(name))
        }
    }
}

impl std::str::FromStr for CellName {
    type Err = NotACellName;

    fn from_str(name: &str) -> Result<CellName, NotACellName> {
        CellName::try_from(name.to_owned())
    }
}

impl From<CellName> for String {
    fn from(name: CellName) -> String {
        name.0
    }
}

impl std::fmt::Display for CellName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// What a cell tells the gateway of itself, twice a second.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct CellInfo {
    pub name: CellName,
    /// What the cell offers.
    pub experiments: Vec<ExperimentId>,
    pub mounted: Option<ExperimentId>,
    pub lab: Readiness,
    /// The run under way, by number.
    pub run: Option<u64>,
    pub operator: Option<Person>,
    /// Who waits for control at the cell itself.
    pub line: u32,
}

impl CellInfo {
    /// Whether an operator arriving now would take control at once.
    pub fn is_free(&self) -> bool {
        self.operator.is_none() && self.line == 0
    }
}

/// One cell as the gateway sees it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct CellStatus {
    #[serde(flatten)]
    pub info: CellInfo,
    /// Guests watching this cell through the gateway.
    pub watchers: u32,
}

/// The gateway's state for its administrator (`GET /status`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GatewayStatus {
    /// The cells up now, by name.
    pub cells: Vec<CellStatus>,
    /// Guests welcomed at the gateway.
    pub connected: u32,
    /// Operators waiting at the gateway for any free cell, first first.
    pub line: Vec<Person>,
}
