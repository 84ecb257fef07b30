//! Driving from a stream of velocities (Foxglove's Teleop panel, ROS 2's
//! `/cmd_vel`) as the Guests' stick drives: paced by events, the next
//! command going when the feedback of the last has come, with the newest
//! velocity. A velocity older than the watchdog is not sent: with none
//! newer, the lab's watchdog stops the robot.

use std::time::Instant;

use vl_core::{Drive, GuestMessage, HostMessage, Role, WATCHDOG};

/// What a client's driving stands at.
#[derive(Default)]
pub struct Pacer {
    operator: bool,
    /// The run's last command sent, and the newest feedback's event.
    sent: u64,
    seen: u64,
    running: bool,
    /// The newest drive not yet sent, and when it came.
    pending: Option<(Drive, Instant)>,
}

impl Pacer {
    /// Takes what the hub told this client.
    pub fn heard(&mut self, message: &HostMessage) {
        match message {
            HostMessage::Welcome { role, .. } | HostMessage::Role { role, .. } => {
                self.operator = *role == Role::Operator;
            }
            HostMessage::Started { event } => {
                (self.sent, self.seen, self.running) = (*event, *event, true);
            }
            HostMessage::Done { .. } => self.running = false,
            _ => {}
        }
    }

    pub fn operator(&self) -> bool {
        self.operator
    }

    pub fn running(&self) -> bool {
        self.running
    }

    /// The operator asks for `drive`: a command now, when none is in
    /// flight; else it waits for the feedback.
    pub fn drive(&mut self, drive: Drive) -> Option<GuestMessage> {
        self.pending = Some((drive, Instant::now()));
        self.next()
    }

    /// The newest feedback is of `event`: the next command, if one waits.
    pub fn feedback(&mut self, event: u64) -> Option<GuestMessage> {
        self.seen = self.seen.max(event);
        self.next()
    }

    fn next(&mut self) -> Option<GuestMessage> {
        if !(self.operator && self.running) || self.seen < self.sent {
            return None;
        }
        let (drive, at) = self.pending.take()?;
        if at.elapsed() > WATCHDOG {
            return None;
        }
        self.sent += 1;
        Some(GuestMessage::Command {
            event: self.sent,
            seen: Some(self.seen),
            drive,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn velocity(v: f64, w: f64) -> Drive {
        Drive::Velocity { v, w }
    }

    #[test]
    fn drives_are_paced_by_feedback_and_only_the_operator_s_count() {
        let mut pacer = Pacer::default();
        assert_eq!(pacer.drive(velocity(50.0, 0.0)), None, "not the operator");
        pacer.heard(&HostMessage::Role {
            role: Role::Operator,
            resume: None,
            slot_s: None,
            ended: None,
        });
        assert_eq!(pacer.drive(velocity(50.0, 0.0)), None, "no run yet");
        pacer.heard(&HostMessage::Started { event: 10 });
        let Some(GuestMessage::Command { event, drive, .. }) = pacer.drive(velocity(50.0, 0.5))
        else {
            panic!("the first command goes at once")
        };
        assert_eq!((event, drive), (11, velocity(50.0, 0.5)));
        assert_eq!(pacer.drive(velocity(20.0, 0.0)), None, "one in flight");
        let Some(GuestMessage::Command { event, drive, .. }) = pacer.feedback(11) else {
            panic!("the newest drive goes with the feedback")
        };
        assert_eq!((event, drive), (12, velocity(20.0, 0.0)));
        assert_eq!(pacer.feedback(12), None, "nothing waits");
    }
}
