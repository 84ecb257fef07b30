//! The administrator's view of the hub: the status `vl host status` and
//! `GET /status` show, the runs of the day, and the devices' faults and
//! returns in the audit log.

use std::collections::VecDeque;
use std::time::{Instant, SystemTime};

use vl_core::{DeviceState, EndReason, ExperimentId, HostStatus, Person, RunRecord};

use super::Hub;
use crate::accounts::audit::AuditEntry;
use vl_record::Level;

const DAY_S: u64 = 86_400;

/// The latest runs, and how many started today.
#[derive(Default)]
pub(super) struct RunLog {
    runs: VecDeque<RunRecord>,
    /// Days since 1970 (UTC) of `today`'s count.
    day: u64,
    today: u32,
}

fn unix_now() -> u64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

impl RunLog {
    pub(super) fn started(&mut self, run: u64, experiment: ExperimentId, user: Option<String>) {
        let now = unix_now();
        if now / DAY_S != self.day {
            (self.day, self.today) = (now / DAY_S, 0);
        }
        self.today += 1;
        if self.runs.len() == HostStatus::RUNS_KEPT {
            self.runs.pop_front();
        }
        self.runs.push_back(RunRecord {
            run,
            experiment,
            started_unix_s: now,
            user,
            ended: None,
        });
    }

    pub(super) fn ended(&mut self, run: u64, reason: EndReason) {
        if let Some(r) = self.runs.iter_mut().find(|r| r.run == run) {
            r.ended = Some(reason);
        }
    }

    /// The newest run that has ended.
    pub(super) fn last_ended(&self) -> Option<RunRecord> {
        self.runs.iter().rev().find(|r| r.ended.is_some()).cloned()
    }

    fn today(&self) -> u32 {
        if unix_now() / DAY_S == self.day {
            self.today
        } else {
            0
        }
    }
}

impl Hub {
    /// The Host's state for its administrator.
    pub(super) fn host_status(&self) -> HostStatus {
        let devices = *self.lab.status.borrow();
        let person = |id: Option<u64>, user: Option<String>| Person { session: id, user };
        let mut status = HostStatus {
            robot: devices.robot,
            camera: devices.camera,
            lab: self.readiness,
            mounted: self.experiment.as_ref().map(|e| e.id.clone()),
            run: self.run,
            operator: (self.operator.is_some() || self.away.is_some())
                .then(|| person(self.operator, self.operator_user.clone())),
            slot_left_s: self.slot_until.map(|until| {
                until
                    .saturating_duration_since(Instant::now())
                    .as_secs_f64()
            }),
            queue: self
                .queue
                .iter()
                .map(|p| person(p.id, p.account.clone()))
                .collect(),
            connected: self.clients.values().filter(|c| c.role.is_some()).count() as u32,
            runs_today: self.run_log.today(),
            runs: self.run_log.runs.iter().cloned().collect(),
            priority: devices.priority,
            recording_stopped: self.lab.record.last_stopped().map(|s| {
                let kept = if s.kept {
                    "kept up to there"
                } else {
                    "deleted: it held nothing"
                };
                format!("{}: {} ({kept})", s.name, s.why)
            }),
            grades: None,
            open_to_anyone: Vec::new(),
        };
        for extension in &self.config.extensions {
            extension.status(&mut status);
        }
        status
    }

    /// Records in the audit log a device that went offline or came back.
    pub(super) fn devices_changed(&mut self) {
        let now = *self.lab.status.borrow();
        let was = std::mem::replace(&mut self.devices, now);
        for (device, before, after) in [
            ("robot", was.robot, now.robot),
            ("camera", was.camera, now.camera),
        ] {
            let event = match (before, after) {
                (b, a) if b == a => continue,
                (_, DeviceState::Offline) => "fault",
                (DeviceState::Offline, _) => "recovered",
                _ => continue,
            };
            self.config
                .audit
                .record(AuditEntry::new(event).detail(format!("the {device}")));
            let state = if after == DeviceState::Offline {
                "does not answer"
            } else {
                "answers again"
            };
            self.record_log(Level::Warning, format!("the {device} {state}"));
        }
    }
}
