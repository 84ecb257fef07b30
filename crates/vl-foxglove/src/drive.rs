//! Driving from Foxglove: its services (take control, mount, start, stop,
//! emergency stop, back to start) and a Twist on `/cmd_vel` (its Teleop
//! panel) become the Guests' messages to the hub, so they go through the
//! same gate, supervisor, safety layer and watchdog as a Guest's. Twists
//! are paced by events as the Guests' stick is: the next command goes
//! when the feedback of the last has come, with the newest Twist.

use serde::Deserialize;
use serde_json::{Value, json};
use vl_core::{Drive, GuestMessage};

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

/// The service that takes the operator's role.
pub(super) const CONTROL: &str = "/vl/control";
/// The topic a Teleop panel publishes on.
pub(super) const CMD_VEL: &str = "/cmd_vel";

impl Service {
    fn name(self) -> &'static str {
        match self {
            Service::Control => CONTROL,
            Service::Mount => "/vl/mount",
            Service::Start => "/vl/start",
            Service::Stop => "/vl/stop",
            Service::EmergencyStop => "/vl/emergency_stop",
            Service::BackToStart => "/vl/back_to_start",
        }
    }

    fn request_schema(self, experiments: &[vl_core::Experiment]) -> Value {
        let string = json!({"type": "string"});
        match self {
            Service::Control => json!({
                "type": "object",
                "description": "Take the operator's role, as an account at a lab with accounts",
                "properties": {"user": string, "password": string},
            }),
            Service::Mount => json!({
                "type": "object",
                "properties": {"experiment": {
                    "type": "string",
                    "enum": experiments.iter().map(|e| e.id.as_str()).collect::<Vec<_>>(),
                }},
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

/// The services, for `advertiseServices`: mount offers `experiments`.
pub(super) fn advertise_services(
    experiments: &[vl_core::Experiment],
) -> tokio_tungstenite::tungstenite::Message {
    let response = json!({
        "type": "object",
        "properties": {"ok": {"type": "boolean"}, "message": {"type": "string"}},
    });
    let services: Vec<Value> = SERVICES
        .iter()
        .enumerate()
        .map(|(id, service)| {
            let request = service.request_schema(experiments);
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

/// A Twist published on `/cmd_vel` as the drive it asks for.
pub(super) fn twist(payload: &[u8]) -> Result<Drive, String> {
    let twist: Twist = serde_json::from_slice(payload)
        .map_err(|e| format!("{CMD_VEL} takes a Twist (linear.x m/s, angular.z rad/s): {e}"))?;
    Drive::from_twist(twist.linear.x, twist.angular.z)
        .ok_or_else(|| format!("{CMD_VEL}: a Twist's speeds are finite numbers"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_twist_is_a_velocity_in_mm_s() {
        let json =
            br#"{"linear": {"x": 0.05, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0.5}}"#;
        assert_eq!(twist(json), Ok(Drive::Velocity { v: 50.0, w: 0.5 }));
        assert!(twist(b"{\"linear\": 3}").is_err());
    }
}
