//! One line for all the cells: operators wait at the gateway, and the
//! first cell free is the first in line's.

use vl_core::{ErrorCode, HostMessage, Role, Wire};

use super::{Front, Link, WELCOME};

const ROLE: &str = r#"{"type":"role""#;

impl Link {
    /// Follows whether the Guest drives at its cell, from what the cell
    /// tells it (a welcome or a role; the rest is not read).
    pub(super) fn follow_role(&mut self, text: &str) {
        if !text.starts_with(WELCOME) && !text.starts_with(ROLE) {
            return;
        }
        if let Ok(HostMessage::Welcome { role, .. } | HostMessage::Role { role, .. }) =
            HostMessage::decode(text)
        {
            self.driving = role == Role::Operator;
        }
    }
}

impl Front {
    /// Guest `id`, watching, asks for control.
    pub(super) fn join_line(&mut self, id: u64) {
        let may_drive = self.guests.get(&id).is_some_and(|g| g.admitted.may_drive);
        if !may_drive {
            return self.refuse(
                id,
                ErrorCode::Unauthorized,
                "your account may watch, not drive",
            );
        }
        // One place per account, as at a Host: more connections of one
        // person do not make the next person wait longer.
        let name = |g: &super::Guest| g.admitted.identity.name().map(str::to_owned);
        if let Some(me) = self.guests.get(&id).and_then(name) {
            let holds = |other: &u64| {
                *other != id && self.guests.get(other).and_then(name) == Some(me.clone())
            };
            let drives = self
                .guests
                .iter()
                .any(|(other, g)| holds(other) && g.link.as_ref().is_some_and(|l| l.driving));
            if drives || self.line.iter().any(holds) {
                let why = if drives {
                    format!("{me} drives already: one place per account")
                } else {
                    format!("{me} has a place in line already: one place per account")
                };
                return self.refuse(id, ErrorCode::NotAllowedNow, why);
            }
        }
        if !self.line.contains(&id) {
            self.line.push_back(id);
        }
        self.tell_line();
    }

    /// Guest `id` no longer waits.
    pub(super) fn leave_line(&mut self, id: u64) {
        self.line.retain(|&waiting| waiting != id);
        let length = self.line.len() as u32;
        let out = HostMessage::Queue {
            position: None,
            length,
            wait_s: None,
        };
        self.tell(id, &out);
        self.tell_line();
    }

    /// Tells everyone in line where they stand.
    fn tell_line(&mut self) {
        let length = self.line.len() as u32;
        let line: Vec<u64> = self.line.iter().copied().collect();
        for (at, id) in line.into_iter().enumerate() {
            let position = Some(at as u32 + 1);
            self.tell(
                id,
                &HostMessage::Queue {
                    position,
                    length,
                    wait_s: None,
                },
            );
        }
    }

    /// Gives the first in line the first free cell, while there are both.
    pub(super) async fn serve_line(&mut self) {
        self.line.retain(|id| self.guests.contains_key(id));
        while let Some(&id) = self.line.front() {
            let Some(cell) = self.free_cell() else { return };
            self.line.pop_front();
            self.link(id, cell, vl_core::PROTOCOL_VERSION, None, true)
                .await;
            self.tell_line();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_role_is_told_by_its_start() {
        let role = HostMessage::Role {
            role: Role::Operator,
            resume: None,
            slot_s: None,
            ended: None,
        };
        assert!(role.encode().starts_with(ROLE));
        assert!(!HostMessage::Bye.encode().starts_with(ROLE));
    }
}
