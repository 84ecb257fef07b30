//! What the gateway's administrator sees (`GET /status`).

use vl_core::{CellStatus, GatewayStatus, Person};

use super::Front;

impl Front {
    /// The cells up (those that said how they are), who watches each,
    /// who is welcomed and who waits.
    pub(super) fn status(&self) -> GatewayStatus {
        let cells = self
            .cells
            .values()
            .filter_map(|cell| {
                Some(CellStatus {
                    info: cell.info.clone()?,
                    watchers: cell.watchers.len() as u32,
                })
            })
            .collect();
        let person = |id: &u64| Person {
            session: Some(*id),
            user: self
                .guests
                .get(id)
                .and_then(|g| g.admitted.identity.name().map(str::to_owned)),
        };
        GatewayStatus {
            cells,
            connected: self.guests.values().filter(|g| g.role.is_some()).count() as u32,
            line: self.line.iter().map(person).collect(),
        }
    }
}
