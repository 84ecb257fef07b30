//! The line for control: observers who ask to drive wait in turn, first
//! come first served; the operator's slot, when slots have a length, ends
//! by handing control to the next in line (the run stopped, the lab made
//! ready); a place held by an account survives a dropped link for the
//! grace, so a reconnect keeps it. An administrator may end anyone's
//! turn or place.

use std::time::Instant;

use tracing::info;
use vl_core::{Action, EndReason, ErrorCode, HostMessage, Role};

use super::access::secret;
use super::{Hub, ToConnection};
use crate::accounts::audit::Entry;
use crate::accounts::gate::Identity;
use crate::accounts::users::AccountRole;
use crate::lab::LabRequest;

/// Someone's place in the line.
pub(super) struct Place {
    /// Their connection; none while their link is down.
    id: Option<u64>,
    /// The account that holds the place across reconnects.
    account: Option<String>,
    /// A place whose link dropped is kept until then.
    away_until: Option<Instant>,
}

impl Hub {
    /// An observer asks for control: it gets it at once if no one drives
    /// or waits, else a place at the end of the line.
    pub(super) fn join_queue(&mut self, id: u64) {
        let Some(client) = self.clients.get(&id) else {
            return;
        };
        if !client.admitted.may_drive {
            return self.refuse(
                id,
                ErrorCode::Unauthorized,
                "to ask for control, log in with an account that may drive",
            );
        }
        if self.queue.iter().any(|p| p.id == Some(id)) {
            return self.refuse(id, ErrorCode::NotAllowedNow, "you are in line already");
        }
        let account = self.user_of(id);
        self.queue.push_back(Place {
            id: Some(id),
            account: account.clone(),
            away_until: None,
        });
        self.config
            .audit
            .record(Entry::new("queued").connection(id).user(account.as_deref()));
        self.grant_next();
        self.tell_queue();
    }

    pub(super) fn leave_queue(&mut self, id: u64) {
        self.queue.retain(|p| p.id != Some(id));
        self.send(
            id,
            HostMessage::Queue {
                position: None,
                length: self.queue.len() as u32,
                wait_s: None,
            },
        );
        self.tell_queue();
    }

    /// A queued client's link dropped (`meant`: it left): an account's
    /// place is kept for the grace, anyone else's is given up.
    pub(super) fn queued_left(&mut self, id: u64, meant: bool) {
        let grace = self.config.grace;
        for place in self.queue.iter_mut().filter(|p| p.id == Some(id)) {
            place.id = None;
            if place.account.is_some() && !meant && !grace.is_zero() {
                place.away_until = Some(Instant::now() + grace);
            }
        }
        self.queue
            .retain(|p| p.id.is_some() || p.away_until.is_some());
        self.tell_queue();
    }

    /// A client welcomed with an account takes back the place that account
    /// held while its link was down.
    pub(super) fn reclaim_place(&mut self, id: u64) {
        let Some(account) = self.user_of(id) else {
            return;
        };
        if let Some(place) = self
            .queue
            .iter_mut()
            .find(|p| p.id.is_none() && p.account.as_deref() == Some(&account))
        {
            place.id = Some(id);
            place.away_until = None;
            info!(connection = id, account, "back in line");
            self.tell_queue();
        }
    }

    /// Gives control to the first in line who is here, when no one has it.
    pub(super) fn grant_next(&mut self) {
        if self.operator.is_some() || self.away.is_some() {
            return;
        }
        while let Some(place) = self.queue.pop_front() {
            if let Some(id) = place.id {
                self.grant(id);
                self.tell_queue();
                return;
            }
        }
    }

    fn grant(&mut self, id: u64) {
        self.operator = Some(id);
        self.resume = Some(secret());
        self.slot_until = self.config.slot.map(|slot| Instant::now() + slot);
        let user = self.user_of(id);
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(Role::Operator);
            let _ = client.out.try_send(ToConnection::Subscribe);
        }
        info!(connection = id, "control granted");
        self.config
            .audit
            .record(Entry::new("granted").connection(id).user(user.as_deref()));
        self.send(
            id,
            HostMessage::Role {
                role: Role::Operator,
                resume: self.resume.clone(),
                slot_s: self.config.slot.map(|s| s.as_secs_f64()),
            },
        );
    }

    /// Gives up places whose grace ran out; ends the operator's slot when
    /// its time is up and someone waits (the run stopped, control handed
    /// on); with no one waiting it runs on for another slot.
    pub(super) fn check_slot(&mut self) {
        // Places whose grace ran out are given up, slots or not.
        let before = self.queue.len();
        self.queue
            .retain(|p| p.id.is_some() || p.away_until.is_some_and(|t| t > Instant::now()));
        if self.queue.len() != before {
            self.tell_queue();
        }
        let (Some(until), Some(slot), Some(id)) =
            (self.slot_until, self.config.slot, self.operator)
        else {
            return;
        };
        if until > Instant::now() {
            return;
        }
        if !self.queue.iter().any(|p| p.id.is_some()) {
            self.slot_until = Some(until + slot);
            return self.send(
                id,
                HostMessage::Role {
                    role: Role::Operator,
                    resume: None,
                    slot_s: Some(slot.as_secs_f64()),
                },
            );
        }
        info!(connection = id, "the operator's slot ended");
        self.config
            .audit
            .record(Entry::new("slot_ended").connection(id));
        if self.supervisor.allows(Action::Stop) {
            self.lab.request(LabRequest::Finish(EndReason::SlotEnded));
        }
        self.release_operator();
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(Role::Observer);
        }
        self.send(
            id,
            HostMessage::Role {
                role: Role::Observer,
                resume: None,
                slot_s: None,
            },
        );
    }

    /// An administrator ends `session`'s turn (its run stops, it watches,
    /// the next in line drives) or its place in line.
    pub(super) fn kick(&mut self, id: u64, session: u64) {
        let admin = self.clients.get(&id).is_some_and(|c| {
            matches!(
                c.admitted.identity,
                Identity::Account {
                    role: AccountRole::Admin,
                    ..
                }
            )
        });
        if !admin {
            return self.refuse(
                id,
                ErrorCode::Unauthorized,
                "only the lab's administrators may end someone's turn",
            );
        }
        let by = self.user_of(id);
        let entry = |what: &str| {
            Entry::new("kicked")
                .connection(session)
                .user(by.as_deref())
                .detail(what.to_owned())
        };
        if self.operator == Some(session) {
            self.config.audit.record(entry("control"));
            if self.supervisor.allows(Action::Stop) {
                self.lab.request(LabRequest::Finish(EndReason::Kicked));
            }
            self.release_operator();
            if let Some(client) = self.clients.get_mut(&session) {
                client.role = Some(Role::Observer);
            }
            let watch = HostMessage::Role {
                role: Role::Observer,
                resume: None,
                slot_s: None,
            };
            return self.send(session, watch);
        }
        if self.queue.iter().any(|p| p.id == Some(session)) {
            self.config.audit.record(entry("place in line"));
            return self.leave_queue(session);
        }
        self.refuse(
            id,
            ErrorCode::NotAllowedNow,
            format!("session {session} neither drives nor waits in line"),
        );
    }

    /// Tells everyone in line where they stand.
    pub(super) fn tell_queue(&mut self) {
        let length = self.queue.len() as u32;
        let waiting: Vec<(usize, u64)> = self
            .queue
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.id.map(|id| (i, id)))
            .collect();
        for (i, id) in waiting {
            let wait_s = self.wait_s(i);
            self.send(
                id,
                HostMessage::Queue {
                    position: Some(i as u32 + 1),
                    length,
                    wait_s,
                },
            );
        }
    }

    /// The longest the one at `index` in line waits: what is left of the
    /// slot under way and a whole slot for each ahead of them.
    fn wait_s(&self, index: usize) -> Option<f64> {
        let slot = self.config.slot?.as_secs_f64();
        let now = Instant::now();
        let current = self
            .slot_until
            .filter(|_| self.operator.is_some())
            .map_or(0.0, |until| {
                until.saturating_duration_since(now).as_secs_f64()
            });
        Some(current + slot * index as f64)
    }
}
