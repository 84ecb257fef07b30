//! Ending someone's time at the lab from outside their own connection: an
//! administrator's kick, or their account removed (or no longer allowed to
//! drive) in the accounts file while they are connected. Either ends their
//! turn or place and every connection of the account, so that no
//! connection left open asks for control again.

use vl_core::{AccessEvent, Action, EndReason, ErrorCode, HostMessage, Role};

use super::{Hub, ToConnection};
use crate::accounts::audit::AuditEntry;
use crate::accounts::gate::ACCOUNT_ENDED;
use crate::accounts::users::Users;
use crate::lab::LabRequest;

impl Hub {
    /// An administrator ends `session`'s turn (its run stops, the next in
    /// line drives) or its place in line, and every connection of its
    /// account (or the session itself, without one).
    pub(super) fn kick(&mut self, id: u64, session: u64) {
        let admin = self
            .clients
            .get(&id)
            .is_some_and(|c| c.admitted.identity.is_admin());
        if !admin {
            return self.refuse(
                id,
                ErrorCode::Unauthorized,
                "only the lab's administrators may end someone's turn",
            );
        }
        if !self.clients.contains_key(&session) {
            return self.refuse(
                id,
                ErrorCode::NotAllowedNow,
                format!("no session {session} is connected"),
            );
        }
        let by = self.user_of(id);
        let kicked = self.user_of(session);
        self.end_turn(session, AuditEntry::new("kicked").user(by.as_deref()));
        let ended: Vec<u64> = match &kicked {
            Some(account) => self.connections_of(account),
            None => vec![session],
        };
        let why = "an administrator ended your session at this lab";
        self.end_connections(ended.into_iter().filter(|&c| c != id), why);
    }

    /// The accounts file was read again: every connection of an account
    /// that is gone, or that drove and may no longer, ends (its turn and
    /// place first); a turn or place held for one whose link is down is
    /// given up too.
    pub(super) fn accounts_changed(&mut self, users: &Users) {
        let mut ended: Vec<String> = self
            .clients
            .values()
            .filter(|c| c.admitted.ended_by(users))
            .filter_map(|c| c.admitted.identity.name().map(str::to_owned))
            .collect();
        ended.sort();
        ended.dedup();
        for account in &ended {
            let entry = || AuditEntry::new("account_ended").user(Some(account));
            let connections = self.connections_of(account);
            match connections
                .iter()
                .find(|&&c| self.operator == Some(c) || self.queue.iter().any(|p| p.id == Some(c)))
            {
                Some(&session) => self.end_turn(session, entry()),
                None => self.config.audit.record(entry().detail("session")),
            }
            self.end_connections(connections.into_iter(), ACCOUNT_ENDED);
        }
        self.drop_absent(users);
    }

    /// Turns and places held across a dropped link for accounts that are
    /// gone end too.
    fn drop_absent(&mut self, users: &Users) {
        let gone = |account: Option<&str>| account.is_some_and(|a| users.role_of(a).is_none());
        if self.away.is_some() && gone(self.operator_user.as_deref()) {
            self.config.audit.record(
                AuditEntry::new("account_ended")
                    .user(self.operator_user.as_deref())
                    .detail("control, held for the grace"),
            );
            self.away = None;
            if self.supervisor.allows(Action::Stop) {
                self.lab.request(LabRequest::Finish(EndReason::Kicked));
            }
            self.release_operator(AccessEvent::Kick);
        }
        while let Some(index) = self
            .queue
            .iter()
            .position(|p| p.id.is_none() && gone(p.account.as_deref()))
        {
            self.drop_place(index, AccessEvent::Kick);
            self.tell_queue();
        }
    }

    /// Every connection of `account`.
    fn connections_of(&self, account: &str) -> Vec<u64> {
        self.clients
            .keys()
            .copied()
            .filter(|&c| self.user_of(c).as_deref() == Some(account))
            .collect()
    }

    /// Closes `connections`, each told `why`.
    fn end_connections(&mut self, connections: impl Iterator<Item = u64>, why: &str) {
        for connection in connections {
            if let Some(client) = self.clients.get(&connection) {
                let _ = client
                    .out
                    .try_send(ToConnection::End(ErrorCode::Unauthorized, why.to_owned()));
            }
        }
    }

    /// Ends the turn or the place in line `session` holds, audited as
    /// `entry` says, with what it held.
    fn end_turn(&mut self, session: u64, entry: AuditEntry) {
        let entry = entry.connection(session);
        if self.operator == Some(session) {
            self.config.audit.record(entry.detail("control"));
            if self.supervisor.allows(Action::Stop) {
                self.lab.request(LabRequest::Finish(EndReason::Kicked));
            }
            self.release_operator(AccessEvent::Kick);
            if let Some(client) = self.clients.get_mut(&session) {
                client.role = Some(Role::Observer);
            }
            let watch = HostMessage::Role {
                role: Role::Observer,
                resume: None,
                slot_s: None,
                ended: Some(EndReason::Kicked),
            };
            return self.send(session, watch);
        }
        if self.queue.iter().any(|p| p.id == Some(session)) {
            self.config.audit.record(entry.detail("place in line"));
            return self.leave_queue(session, AccessEvent::Kick);
        }
        self.config.audit.record(entry.detail("session"));
    }
}
