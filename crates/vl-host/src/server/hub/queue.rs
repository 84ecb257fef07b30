//! The line for control: observers who ask to drive wait in turn, first
//! come first served; the operator's slot, when slots have a length, ends
//! by handing control to the next in line (the run stopped, the lab made
//! ready); a place held by an account survives a dropped link for the
//! grace, so a reconnect keeps it. An administrator may end anyone's
//! turn or place.
//!
//! Every step is an event of the access net the supervisor runs: the line
//! here is the order, the net says whether the step may happen (one
//! operator, a grant only to the head, the run stopped before a slot
//! ends). The first in line holds the net's head.

use std::time::Instant;

use tracing::{info, warn};
use vl_core::{AccessEvent, Action, EndReason, ErrorCode, HostMessage, Role, Seat};

use super::{Hub, ToConnection};
use crate::accounts::audit::AuditEntry;
use crate::lab::LabRequest;
use crate::secret::secret;

/// The line is told of its changes at most this often.
const TELL_LINE_EVERY: std::time::Duration = std::time::Duration::from_millis(200);

/// Someone's place in the line.
pub(super) struct Spot {
    /// Their connection; none while their link is down.
    pub(super) id: Option<u64>,
    /// The account that holds the place across reconnects.
    pub(super) account: Option<String>,
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
        // One place per account: more connections of one person do not
        // make the next person wait more slots.
        let account = self.user_of(id);
        if let Some(name) = account.as_deref() {
            let drives = self.operator_user.as_deref() == Some(name);
            if drives
                || self
                    .queue
                    .iter()
                    .any(|p| p.account.as_deref() == Some(name))
            {
                let why = if drives {
                    format!("{name} drives already: one place per account")
                } else {
                    format!("{name} has a place in line already: one place per account")
                };
                return self.refuse(id, ErrorCode::NotAllowedNow, why);
            }
        }
        if let Err(e) = self
            .supervisor
            .access(&[(AccessEvent::Ask, Seat::Observer)])
        {
            return self.refuse(id, ErrorCode::NotAllowedNow, e.to_string());
        }
        self.queue.push_back(Spot {
            id: Some(id),
            account: account.clone(),
            away_until: None,
        });
        self.config.audit.record(
            AuditEntry::new("queued")
                .connection(id)
                .user(account.as_deref()),
        );
        self.fill_head();
        self.grant_next();
        self.tell_queue();
    }

    /// `id` gives up its place in line (`LeaveQueue`) or is removed from it
    /// (`Kick`).
    pub(super) fn leave_queue(&mut self, id: u64, how: AccessEvent) {
        let left = self.queue.iter().position(|p| p.id == Some(id));
        if let Some(index) = left {
            self.drop_place(index, how);
        }
        self.send(
            id,
            HostMessage::Queue {
                position: None,
                length: self.queue.len() as u32,
                wait_s: None,
            },
        );
        // Only a line that changed is told again: a burst of leave_queue
        // from someone not in it costs the others nothing.
        if left.is_some() {
            self.tell_queue();
        }
    }

    /// A queued client's link dropped (`meant`: it left): an account's
    /// place is kept for the grace, anyone else's is given up.
    pub(super) fn queued_left(&mut self, id: u64, meant: bool) {
        let grace = self.config.grace;
        let Some(index) = self.queue.iter().position(|p| p.id == Some(id)) else {
            return;
        };
        let place = &mut self.queue[index];
        place.id = None;
        if place.account.is_some() && !meant && !grace.is_zero() {
            place.away_until = Some(Instant::now() + grace);
        } else {
            self.drop_place(index, AccessEvent::LeaveQueue);
        }
        self.tell_queue();
    }

    /// Takes the place at `index` out of the line as `how` says, in the
    /// access net too, and moves the next up to the head.
    pub(super) fn drop_place(&mut self, index: usize, how: AccessEvent) {
        let seat = if index == 0 {
            Seat::Head
        } else {
            Seat::Waiting
        };
        self.seat(how, seat);
        self.queue.remove(index);
        self.fill_head();
    }

    /// The first in line moves up to the net's head when it is empty.
    fn fill_head(&mut self) {
        if !self.queue.is_empty() && self.supervisor.seated(Seat::Head) == Some(0) {
            self.seat(AccessEvent::Advance, Seat::Waiting);
        }
    }

    /// Fires an access event the line's own order says is due; a refusal
    /// means the access net (a changed chart, say) forbids what the hub
    /// does, which the log says. Whether it fired.
    pub(super) fn seat(&mut self, event: AccessEvent, seat: Seat) -> bool {
        match self.supervisor.access(&[(event, seat)]) {
            Ok(()) => true,
            Err(e) => {
                warn!("{e}");
                false
            }
        }
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
        // A head whose link is down loses the place: the next is here.
        while let Some(head) = self.queue.front() {
            let Some(id) = head.id else {
                self.drop_place(0, AccessEvent::LeaveQueue);
                continue;
            };
            if !self.seat(AccessEvent::Grant, Seat::Head) {
                return;
            }
            self.queue.pop_front();
            self.fill_head();
            self.grant(id);
            self.tell_queue();
            return;
        }
    }

    fn grant(&mut self, id: u64) {
        self.operator = Some(id);
        self.operator_user = self.user_of(id);
        self.resume = Some(secret());
        self.slot_until = self.config.slot.map(|slot| Instant::now() + slot);
        let user = self.user_of(id);
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(Role::Operator);
            let _ = client.out.try_send(ToConnection::Subscribe);
        }
        info!(connection = id, "control granted");
        self.config.audit.record(
            AuditEntry::new("granted")
                .connection(id)
                .user(user.as_deref()),
        );
        self.send(
            id,
            HostMessage::Role {
                role: Role::Operator,
                resume: self.resume.clone(),
                slot_s: self.config.slot.map(|s| s.as_secs_f64()),
                ended: None,
            },
        );
        // Told after the role, so the new operator knows they may use it.
        self.mount_kept();
    }

    /// Gives up places whose grace ran out; ends the operator's slot when
    /// its time is up and someone waits (the run stopped, control handed
    /// on); with no one waiting it runs on for another slot.
    pub(super) fn check_slot(&mut self) {
        // Places whose grace ran out are given up, slots or not.
        let now = Instant::now();
        let lapsed: Vec<usize> = (self.queue.iter().enumerate())
            .filter(|(_, p)| p.id.is_none() && p.away_until.is_none_or(|t| t <= now))
            .map(|(i, _)| i)
            .collect();
        // From the back, so the indices ahead stay where they are.
        for &index in lapsed.iter().rev() {
            self.drop_place(index, AccessEvent::LeaveQueue);
        }
        if !lapsed.is_empty() {
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
                    ended: None,
                },
            );
        }
        info!(connection = id, "the operator's slot ended");
        let driver = self.operator_user.clone();
        self.config.audit.record(
            AuditEntry::new("slot_ended")
                .connection(id)
                .user(driver.as_deref()),
        );
        if self.supervisor.allows(Action::Stop) {
            self.lab.request(LabRequest::Finish(EndReason::SlotEnded));
        }
        self.release_operator(AccessEvent::SlotEnd);
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(Role::Observer);
        }
        self.send(
            id,
            HostMessage::Role {
                role: Role::Observer,
                resume: None,
                slot_s: None,
                ended: Some(EndReason::SlotEnded),
            },
        );
    }

    /// Where the hub's own bookkeeping (the operator, one held for the
    /// grace, the line) and the access net's seats differ, if they do;
    /// checked after every step in debug builds, with the shipped nets.
    pub(super) fn seats_apart(&self) -> Option<String> {
        let driving = u32::from(self.operator.is_some() || self.away.is_some());
        let line = self.queue.len() as u32;
        let hub = [driving, line.min(1), line.saturating_sub(1)];
        let seats = [Seat::Operator, Seat::Head, Seat::Waiting];
        let net = seats.map(|seat| self.supervisor.seated(seat));
        (net != hub.map(Some)).then(|| format!("hub {hub:?}, access net {net:?}"))
    }

    /// The line changed: everyone in it is told where they stand, at once
    /// or, after a change told less than [`TELL_LINE_EVERY`] ago, with the
    /// next (a burst of changes is told once, not once each).
    pub(super) fn tell_queue(&mut self) {
        self.line_changed = true;
        self.tell_line_if_due();
    }

    /// Tells the line of a change not yet told, if it is time to.
    pub(super) fn tell_line_if_due(&mut self) {
        if !self.line_changed
            || self
                .line_told
                .is_some_and(|told| told.elapsed() < TELL_LINE_EVERY)
        {
            return;
        }
        self.line_changed = false;
        self.line_told = Some(Instant::now());
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
        // The operator hears how many wait after them.
        if let Some(operator) = self.operator {
            self.send(
                operator,
                HostMessage::Queue {
                    position: None,
                    length,
                    wait_s: None,
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
