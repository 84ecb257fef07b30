//! Who may drive: the hello that makes an operator or an observer, the
//! operator's lease, the grace a dropped operator keeps, and leaving.

use std::time::Instant;

use tracing::info;
use vl_core::{
    AccessEvent, Action, EndReason, ErrorCode, HostMessage, PROTOCOL_VERSION, Role, Seat,
};

use super::{Away, Hub, ToConnection};
use crate::accounts::audit::AuditEntry;
use crate::accounts::gate::Admitted;
use crate::lab::LabRequest;
use crate::secret::secret;

impl Hub {
    /// A hello the gate let through: a first one, or an observer (or an
    /// operator who lost the lease) asking to drive.
    pub(super) fn greet(
        &mut self,
        id: u64,
        admitted: Admitted,
        protocol: u32,
        role: Role,
        resume: Option<String>,
    ) {
        match self.clients.get(&id).map(|c| c.role) {
            Some(None) => {}
            Some(Some(Role::Observer)) if role == Role::Operator => {}
            Some(Some(_)) => {
                return self.refuse(id, ErrorCode::NotAllowedNow, "already said hello");
            }
            None => return,
        }
        if let Some(client) = self.clients.get_mut(&id) {
            client.admitted = admitted;
        }
        self.hello(id, protocol, role, resume);
        if self
            .clients
            .get(&id)
            .is_some_and(|c| c.role == Some(Role::Observer))
        {
            self.reclaim_place(id);
        }
    }

    fn hello(&mut self, id: u64, protocol: u32, role: Role, resume: Option<String>) {
        if protocol != PROTOCOL_VERSION {
            return self.refuse_hello(
                id,
                ErrorCode::ProtocolMismatch,
                format!("this Host speaks protocol {PROTOCOL_VERSION}, not {protocol}"),
            );
        }
        if role == Role::Operator && !self.take_control(id, resume.as_deref()) {
            return;
        }
        let user = self.user_of(id);
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(role);
            let _ = client.out.try_send(ToConnection::Subscribe);
        }
        info!(connection = id, ?role, "welcomed");
        self.config.audit.record(
            AuditEntry::new("welcome")
                .connection(id)
                .user(user.as_deref())
                .detail(role.to_string()),
        );
        let resume = (role == Role::Operator)
            .then(|| self.resume.clone())
            .flatten();
        self.send(id, self.welcome(id, role, user, resume));
        // An operator's slot, when slots have a length, is told with the role.
        if let (Role::Operator, Some(until)) = (role, self.slot_until) {
            let left = until.saturating_duration_since(Instant::now());
            self.send(
                id,
                HostMessage::Role {
                    role,
                    resume: None,
                    slot_s: Some(left.as_secs_f64()),
                    ended: None,
                },
            );
        }
        // A late observer catches up on what is mounted and defined.
        for message in self.catch_up() {
            self.send(id, message);
        }
        // An operator back within the grace takes up the run where it stood.
        if role == Role::Operator && self.supervisor.allows(Action::Stop) {
            self.last_command = Instant::now();
            self.lab.request(LabRequest::Hold(false));
            self.send(
                id,
                HostMessage::Started {
                    event: self.last_event,
                },
            );
        }
    }

    /// The welcome of `session` in `role`.
    pub(super) fn welcome(
        &self,
        session: u64,
        role: Role,
        user: Option<String>,
        resume: Option<String>,
    ) -> HostMessage {
        HostMessage::Welcome {
            session,
            role,
            experiments: self.config.experiments.experiments().cloned().collect(),
            resume,
            user,
            scene: Some(Box::new(self.scene())),
        }
    }

    /// What a late observer catches up on after its welcome: what is
    /// mounted and defined, the forecast, the lab's status, the net's state.
    pub(super) fn catch_up(&self) -> Vec<HostMessage> {
        let mut told: Vec<HostMessage> = self.mounted().into_iter().collect();
        if let Some(definition) = self.definition.clone() {
            told.push(HostMessage::Defined { definition });
            // And what the lab's twin made of it, when it has tried it.
            if let Some(verdict) = self.verdict.clone() {
                told.push(HostMessage::Forecast(Box::new(verdict)));
            }
        }
        told.push(self.status());
        told.push(HostMessage::State(Box::new(self.supervisor.state())));
        told
    }

    /// Refuses a hello, in the audit log too: who was turned away, and why.
    fn refuse_hello(&mut self, id: u64, code: ErrorCode, message: impl Into<String>) {
        let message = message.into();
        let user = self.user_of(id);
        self.config.audit.record(
            AuditEntry::new("refused")
                .connection(id)
                .user(user.as_deref())
                .detail(format!("{code}: {message}")),
        );
        self.refuse(id, code, message);
    }

    /// Makes `id` the operator, when the role is free and no one waits for
    /// it (or it is theirs, held since their link dropped, and `resume`
    /// says so); else tells them why not.
    fn take_control(&mut self, id: u64, resume: Option<&str>) -> bool {
        // A secret resumes only its own account's session: someone else's
        // hello that carries it is refused, and the attempt audited.
        let owner = self.operator_user.clone();
        let caller = self.user_of(id);
        let someone_else = owner.is_some() && caller != owner;
        if let Some(away) = &self.away
            && resume == Some(away.resume.as_str())
            && someone_else
        {
            self.config.audit.record(
                AuditEntry::new("takeover_refused")
                    .connection(id)
                    .user(caller.as_deref())
                    .detail(format!(
                        "the resume secret of {}'s session",
                        owner.as_deref().unwrap_or("another")
                    )),
            );
            self.refuse_hello(
                id,
                ErrorCode::OperatorTaken,
                "that secret resumes another account's session: log in as yourself and ask for control",
            );
            return false;
        }
        let returning = match &self.away {
            Some(away) if resume == Some(away.resume.as_str()) => true,
            Some(away) => {
                let left = away.until.saturating_duration_since(Instant::now());
                self.refuse_hello(
                    id,
                    ErrorCode::OperatorTaken,
                    format!(
                        "the operator's link dropped; the role is held for them for {:.0} more s",
                        left.as_secs_f64().ceil()
                    ),
                );
                return false;
            }
            None => false,
        };
        if self.operator.is_some() {
            self.refuse_hello(
                id,
                ErrorCode::OperatorTaken,
                "another operator is driving; say hello again as an observer to watch, and ask for control to be next",
            );
            return false;
        }
        if !returning && !self.queue.is_empty() {
            let waiting = self.queue.len();
            self.refuse_hello(
                id,
                ErrorCode::OperatorTaken,
                format!("{waiting} waiting for control before you: watch as an observer and ask for control"),
            );
            return false;
        }
        // Asking and being granted at once, when the line is empty.
        if !returning
            && let Err(e) = self.supervisor.access(&[
                (AccessEvent::Ask, Seat::Observer),
                (AccessEvent::Advance, Seat::Waiting),
                (AccessEvent::Grant, Seat::Head),
            ])
        {
            self.refuse_hello(id, ErrorCode::NotAllowedNow, e.to_string());
            return false;
        }
        self.operator = Some(id);
        self.operator_user = self.user_of(id);
        if returning {
            self.away = None;
            info!(connection = id, "the operator is back");
        } else {
            self.slot_until = self.config.slot.map(|slot| Instant::now() + slot);
            let entry = AuditEntry::new("granted").connection(id);
            self.config
                .audit
                .record(entry.user(self.operator_user.as_deref()));
        }
        // Every welcome carries a fresh secret, so every drop has its
        // grace (and an old secret, once used, opens nothing).
        self.resume = Some(secret());
        self.mount_kept();
        // Those welcomed see the mount fire; the newcomer's welcome shows
        // the net as it is after it.
        self.tell_state();
        true
    }

    /// An operator who has sent no command for the lease time during a run
    /// loses the run and the role, and stays on as an observer.
    /// A run the Host itself steers along the defined path needs no
    /// commands: its operator is not silent for sending none (a lost one
    /// still ends it, through the connection's pings).
    pub(super) fn check_lease(&mut self) {
        if self
            .away
            .as_ref()
            .is_some_and(|a| a.until <= Instant::now())
        {
            self.away = None;
            info!("the operator did not come back within the grace: the role is free");
            if self.supervisor.allows(Action::Stop) {
                self.lab
                    .request(LabRequest::Finish(EndReason::OperatorLeft));
            }
            self.release_operator(AccessEvent::Leave);
        }
        let Some(id) = self.operator else { return };
        if !self.supervisor.allows(Action::Stop)
            || self.last_command.elapsed() < self.config.lease
            || self.host_follows()
            || self
                .experiment
                .as_ref()
                .is_some_and(|e| !e.takes_commands())
        {
            return;
        }
        let lease = self.config.lease.as_secs_f64();
        info!(
            connection = id,
            "operator silent for {lease} s: the role is free"
        );
        self.lab
            .request(LabRequest::Finish(EndReason::OperatorSilent));
        self.release_operator(AccessEvent::Leave);
        if let Some(client) = self.clients.get_mut(&id) {
            client.role = Some(Role::Observer);
        }
        self.refuse(
            id,
            ErrorCode::Timeout,
            format!("no command for {lease} s: the run ended and you watch now; say hello as operator to drive again"),
        );
    }

    /// Whether runs of what is mounted and defined follow a path on the Host.
    fn host_follows(&self) -> bool {
        match (&self.experiment, &self.definition) {
            (Some(experiment), Some(definition)) => definition.host_follows(experiment.follows()),
            _ => false,
        }
    }

    /// The operator role is free again (`how`: their slot ended, they
    /// left, or were kicked) and the lab back to idle, its run ended first;
    /// the next in line, if any, has it.
    pub(super) fn release_operator(&mut self, how: AccessEvent) {
        let entry = AuditEntry::new("released").user(self.operator_user.take().as_deref());
        self.config.audit.record(
            match self.operator {
                Some(id) => entry.connection(id),
                None => entry,
            }
            .detail(how.to_string()),
        );
        self.operator = None;
        self.resume = None;
        self.slot_until = None;
        if self.supervisor.allows(Action::Release) {
            self.happened(Action::Release);
        }
        self.seat(how, Seat::Operator);
        self.kept = self.experiment.take().or(self.kept.take());
        self.definition = None;
        self.cspace = None;
        self.field = None;
        self.fields.forget();
        self.forecasts.forget();
        self.verdict = None;
        self.grant_next();
    }

    /// A connection closed: if it was the operator, the robot stops; the
    /// lab returns to idle for the next person at once if they meant to leave,
    /// or after the grace if their link dropped and they do not come back.
    pub(super) fn leave(&mut self, id: u64, meant: bool) {
        self.clients.remove(&id);
        if self.operator != Some(id) {
            return self.queued_left(id, meant);
        }
        info!(connection = id, "operator left");
        let running = self.supervisor.allows(Action::Stop);
        // A link that dropped may come back: the role and the run are held
        // for the grace, the robot still; a lab with nothing on it is free.
        if let Some(resume) = self.resume.take()
            && !meant
            && !self.config.grace.is_zero()
            && self.experiment.is_some()
        {
            self.operator = None;
            self.away = Some(Away {
                resume,
                until: Instant::now() + self.config.grace,
            });
            if running {
                self.lab.request(LabRequest::Hold(true));
            }
            return;
        }
        // A run the operator could stop is stopped for them.
        if running {
            self.lab
                .request(LabRequest::Finish(EndReason::OperatorLeft));
        }
        self.release_operator(AccessEvent::Leave);
    }
}
