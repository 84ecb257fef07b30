//! The key expressions cells and gateways meet on: one home for each.
//!
//! | key | from | holds |
//! |---|---|---|
//! | `vl/cells/NAME` | cell | liveliness token: the cell is up |
//! | `vl/cells/NAME/info` | cell | `CellInfo` as JSON, twice a second |
//! | `vl/cells/NAME/messages` | cell | each protocol v1 message its observers are told (JSON text) |
//! | `vl/cells/NAME/feedback` | cell | the newest feedback (protocol v1 JSON text) |
//! | `vl/cells/NAME/frames` | cell | camera frames, as on the Guests' wire |
//! | `vl/cells/NAME/catch_up` | cell (queryable) | what a late observer is told: a JSON array of protocol v1 messages |
//! | `vl/cells/NAME/links/LINK` | gateway | liveliness token: the gateway still holds this Guest |
//! | `vl/cells/NAME/links/LINK/up` | gateway | the Guest's side of a link (`LinkUp`, JSON) |
//! | `vl/cells/NAME/links/LINK/down` | cell | the cell's side of a link (`LinkDown`, JSON) |

use vl_core::{CellName, MAX_TEXT_BYTES};

/// The most a sample on a cell's keys may hold, checked before it is read:
/// a protocol message (and a link's, which wraps one) at most what a
/// Guest's socket takes, with room for the wrapping.
pub(crate) const MOST_TEXT: usize = 2 * MAX_TEXT_BYTES;
/// A camera frame: a JPEG of a large camera, with room to spare.
pub(crate) const MOST_FRAME: usize = 8 << 20;
/// What a late observer is told: several messages.
pub(crate) const MOST_CATCH_UP: usize = 16 << 20;

/// Every cell's liveliness token.
pub(crate) const CELLS: &str = "vl/cells/*";
/// Every cell's info.
pub(crate) const INFOS: &str = "vl/cells/*/info";

pub(crate) fn cell(name: &CellName) -> String {
    format!("vl/cells/{name}")
}

pub(crate) fn info(name: &CellName) -> String {
    format!("vl/cells/{name}/info")
}

pub(crate) fn messages(name: &CellName) -> String {
    format!("vl/cells/{name}/messages")
}

pub(crate) fn feedback(name: &CellName) -> String {
    format!("vl/cells/{name}/feedback")
}

pub(crate) fn frames(name: &CellName) -> String {
    format!("vl/cells/{name}/frames")
}

pub(crate) fn catch_up(name: &CellName) -> String {
    format!("vl/cells/{name}/catch_up")
}

pub(crate) fn link(name: &CellName, link: &str) -> String {
    format!("vl/cells/{name}/links/{link}")
}

/// Every link's liveliness token at a cell.
pub(crate) fn links(name: &CellName) -> String {
    format!("vl/cells/{name}/links/*")
}

pub(crate) fn up(name: &CellName, link: &str) -> String {
    format!("vl/cells/{name}/links/{link}/up")
}

/// Every link's `up` at a cell.
pub(crate) fn ups(name: &CellName) -> String {
    format!("vl/cells/{name}/links/*/up")
}

pub(crate) fn down(name: &CellName, link: &str) -> String {
    format!("vl/cells/{name}/links/{link}/down")
}

/// The cell a key of `vl/cells/NAME/…` is about.
pub(crate) fn cell_of(key: &str) -> Option<CellName> {
    key.strip_prefix("vl/cells/")?
        .split('/')
        .next()?
        .parse()
        .ok()
}

/// The link a key of `vl/cells/NAME/links/LINK[/…]` is about.
pub(crate) fn link_of(key: &str) -> Option<&str> {
    let rest = key.strip_prefix("vl/cells/")?;
    let mut parts = rest.split('/');
    let (_, links, link) = (parts.next()?, parts.next()?, parts.next()?);
    (links == "links").then_some(link)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_their_cell_and_link() {
        let name: CellName = "cell-2".parse().unwrap();
        assert_eq!(cell_of(&info(&name)), Some(name.clone()));
        assert_eq!(cell_of(&cell(&name)), Some(name.clone()));
        assert_eq!(link_of(&up(&name, "g7-3")), Some("g7-3"));
        assert_eq!(link_of(&link(&name, "g7-3")), Some("g7-3"));
        assert_eq!(link_of(&info(&name)), None);
        assert_eq!(cell_of("vl/cells/Not A Name/info"), None);
    }
}
