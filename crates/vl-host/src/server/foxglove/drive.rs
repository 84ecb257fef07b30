//! Driving from Foxglove: its services (take control, mount, start, stop,
//! emergency stop, back to start) and a Twist on `/cmd_vel` (its Teleop
//! panel) become the Guests' messages to the hub, so they go through the
//! same gate, supervisor, safety layer and watchdog as a Guest's. Twists
//! are paced by events as the Guests' stick is: the next command goes
//! when the feedback of the last has come, with the newest Twist.

use std::time::{Duration, Instant};

use serde::Deserialize;
use serde_json::{Value, json};
use vl_core::{Drive, GuestMessage, HostMessage, Role};

/// The services, their ids their places here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Service {
    Control,
    Mount,
    Start,
    Stop,
    EmergencyStop,
    BackToStart,
}

pub(super) const SERVICES: [Service; 6] = [
    Service::Control,
    Service::Mount,
    Service::Start,
    Service::Stop,
    Service::EmergencyStop,
    Service::BackToStart,
];

/// The topic a Teleop panel publishes on.
pub(super) const CMD_VEL: &str = "/cmd_vel";
/// A Twist older than this is not sent: with none newer, the lab's
/// watchdog stops the robot.
const TWIST_FRESH: Duration = Duration::from_millis(500);

impl Service {
    fn name(self) -> &'static str {
        match self {
            Service::Control => "/vl/control",
            Service::Mount => "/vl/mount",
            Service::Start => "/vl/start",
            Service::Stop => "/vl/stop",
            Service::EmergencyStop => "/vl/emergency_stop",
            Service::BackToStart => "/vl/back_to_start",
        }
    }

    fn request_schema(self) -> Value {
        let string = json!({"type": "string"});
        match self {
            Service::Control => json!({
                "type": "object",
                "description": "Take the operator's role, as an account at a lab with accounts",
                "properties": {"user": string, "password": string},
            }),
            Service::Mount => json!({
                "type": "object",
                "properties": {"experiment": {"type": "string", "enum": ["navigation", "teleoperation"]}},
                "required": ["experiment"],
            }),
            _ => json!({"type": "object", "properties": {}}),
        }
    }

    /// The message of the Guests' protocol this call stands for; none for
    /// taking control, which goes through the gate first.
    pub(super) fn message(self, request: &Value) -> Result<Option<GuestMessage>, String> {
        Ok(Some(match self {
            Service::Control => return Ok(None),
            Service::Mount => GuestMessage::Mount {
                experiment: request["experiment"]
                    .as_str()
                    .ok_or("mount needs an experiment: navigation or teleoperation")?
                    .to_owned(),
            },
            Service::Start => GuestMessage::Start,
            Service::Stop => GuestMessage::Stop,
            Service::EmergencyStop => GuestMessage::EmergencyStop,
            Service::BackToStart => GuestMessage::Reset,
        }))
    }
}

/// The services, for `advertiseServices`.
pub(super) fn advertise_services() -> tokio_tungstenite::tungstenite::Message {
    let response = json!({
        "type": "object",
        "properties": {"ok": {"type": "boolean"}, "message": {"type": "string"}},
    });
    let services: Vec<Value> = SERVICES
        .iter()
        .enumerate()
        .map(|(id, service)| {
            let request = service.request_schema();
            json!({
                "id": id,
                "name": service.name(),
                "type": format!("vl{}", service.name()),
                "request": {
                    "encoding": "json",
                    "schemaName": format!("vl{}.Request", service.name()),
                    "schemaEncoding": "jsonschema",
                    "schema": request.to_string(),
                },
                "response": {
                    "encoding": "json",
                    "schemaName": format!("vl{}.Response", service.name()),
                    "schemaEncoding": "jsonschema",
                    "schema": response.to_string(),
                },
            })
        })
        .collect();
    tokio_tungstenite::tungstenite::Message::text(
        json!({"op": "advertiseServices", "services": services}).to_string(),
    )
}

/// A Twist as JSON (ROS's geometry_msgs/Twist, as Foxglove's Teleop panel
/// publishes it): m/s and rad/s.
#[derive(Deserialize)]
struct Twist {
    linear: Axes,
    angular: Axes,
}

#[derive(Deserialize)]
struct Axes {
    #[serde(default)]
    x: f64,
    #[serde(default)]
    z: f64,
}

/// What this client's driving stands at.
#[derive(Default)]
pub(super) struct Driver {
    pub operator: bool,
    /// The run's last command sent, and the newest feedback's event.
    sent: u64,
    seen: u64,
    running: bool,
    /// The newest Twist not yet sent, as a drive, and when it came.
    pending: Option<(Drive, Instant)>,
}

impl Driver {
    /// Takes what the hub told this client.
    pub(super) fn heard(&mut self, message: &HostMessage) {
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

    /// A Twist published on `/cmd_vel`: a command now, when none is in
    /// flight; else it waits for the feedback.
    pub(super) fn twist(&mut self, payload: &[u8]) -> Result<Option<GuestMessage>, String> {
        if !self.operator {
            return Err(format!(
                "only the operator drives: call {} first (as the account that may drive, at a lab with accounts)",
                Service::Control.name()
            ));
        }
        let twist: Twist = serde_json::from_slice(payload)
            .map_err(|e| format!("{CMD_VEL} takes a Twist (linear.x m/s, angular.z rad/s): {e}"))?;
        let (v, w) = (twist.linear.x * 1000.0, twist.angular.z);
        if !(v.is_finite() && w.is_finite()) {
            return Err(format!("{CMD_VEL}: a Twist's speeds are finite numbers"));
        }
        let drive = Drive::Velocity { v, w };
        self.pending = Some((drive, Instant::now()));
        Ok(self.next())
    }

    /// The newest feedback is of `event`: the next command, if one waits.
    pub(super) fn feedback(&mut self, event: u64) -> Option<GuestMessage> {
        self.seen = self.seen.max(event);
        self.next()
    }

    fn next(&mut self) -> Option<GuestMessage> {
        if !(self.operator && self.running) || self.seen < self.sent {
            return None;
        }
        let (drive, at) = self.pending.take()?;
        if at.elapsed() > TWIST_FRESH {
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

    fn twist(x: f64, z: f64) -> Vec<u8> {
        json!({"linear": {"x": x, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": z}})
            .to_string()
            .into_bytes()
    }

    #[test]
    fn twists_are_paced_by_feedback_and_only_the_operator_s_count() {
        let mut driver = Driver::default();
        assert!(driver.twist(&twist(0.05, 0.0)).is_err(), "not the operator");
        driver.heard(&HostMessage::Role {
            role: Role::Operator,
            resume: None,
            slot_s: None,
            ended: None,
        });
        assert_eq!(driver.twist(&twist(0.05, 0.0)), Ok(None), "no run yet");
        driver.heard(&HostMessage::Started { event: 10 });
        let Ok(Some(GuestMessage::Command { event, drive, .. })) = driver.twist(&twist(0.05, 0.5))
        else {
            panic!("the first command goes at once")
        };
        assert_eq!(event, 11);
        assert_eq!(drive, Drive::Velocity { v: 50.0, w: 0.5 });
        assert_eq!(driver.twist(&twist(0.02, 0.0)), Ok(None), "one in flight");
        let Some(GuestMessage::Command { event, drive, .. }) = driver.feedback(11) else {
            panic!("the newest twist goes with the feedback")
        };
        assert_eq!((event, drive), (12, Drive::Velocity { v: 20.0, w: 0.0 }));
        assert_eq!(driver.feedback(12), None, "nothing waits");
        assert!(driver.twist(b"{\"linear\": 3}").is_err());
    }
}
