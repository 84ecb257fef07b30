//! The Foxglove WebSocket protocol's messages, both ways: what a client
//! may send (subscriptions, its own channels, service calls), and what the
//! Host sends (server info, channels, services, data, time, statuses).

use serde::Deserialize;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::{Bytes, Message};
use vl_record::{Topic, View};

/// The channels advertised, their ids their places here.
/// Live: what a recording has but the operator's commands, which only
/// the recorder is handed.
pub(super) const CHANNELS: [Topic; 23] = [
    Topic::Camera,
    Topic::Annotations,
    Topic::Calibration,
    Topic::Pose,
    Topic::Transform,
    Topic::CameraTransform,
    Topic::Scene,
    Topic::Map,
    Topic::CSpace,
    Topic::Path,
    Topic::Seeds,
    Topic::Scan,
    Topic::Motion,
    Topic::Log,
    Topic::Feedback,
    Topic::State,
    Topic::Status,
    Topic::Lab,
    Topic::Definition,
    Topic::Forecast,
    Topic::Started,
    Topic::Summary,
    Topic::RoundTrip,
];

/// Client ops, in text.
#[derive(Deserialize)]
#[serde(tag = "op", rename_all = "camelCase")]
pub(super) enum ClientOp {
    Subscribe {
        subscriptions: Vec<Subscription>,
    },
    #[serde(rename_all = "camelCase")]
    Unsubscribe {
        subscription_ids: Vec<u32>,
    },
    /// The client's own channels, to publish on.
    Advertise {
        channels: Vec<ClientChannel>,
    },
    #[serde(rename_all = "camelCase")]
    Unadvertise {
        channel_ids: Vec<u32>,
    },
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Subscription {
    pub id: u32,
    pub channel_id: u32,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct ClientChannel {
    pub id: u32,
    pub topic: String,
    pub encoding: String,
}

/// Binary opcodes, client to server.
pub(super) const CLIENT_MESSAGE_DATA: u8 = 0x01;
pub(super) const SERVICE_CALL_REQUEST: u8 = 0x02;
/// Binary opcodes, server to client.
const MESSAGE_DATA: u8 = 0x01;
const TIME: u8 = 0x02;
const SERVICE_CALL_RESPONSE: u8 = 0x03;

/// A service call: the service, the call's id (echoed), the payload.
pub(super) struct ServiceCall {
    pub service: u32,
    pub call: u32,
    pub encoding: String,
    pub payload: Bytes,
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
}

impl ServiceCall {
    /// A call request after its opcode.
    pub(super) fn parse(bytes: &Bytes) -> Option<ServiceCall> {
        let service = u32_at(bytes, 1)?;
        let call = u32_at(bytes, 5)?;
        let length = u32_at(bytes, 9)? as usize;
        let encoding = bytes.get(13..13usize.checked_add(length)?)?;
        Some(ServiceCall {
            service,
            call,
            encoding: String::from_utf8(encoding.to_vec()).ok()?,
            payload: bytes.slice(13 + length..),
        })
    }
}

/// A client's message on its channel: the channel and the payload.
pub(super) fn client_data(bytes: &Bytes) -> Option<(u32, Bytes)> {
    Some((u32_at(bytes, 1)?, bytes.slice(5..)))
}

fn text(value: Value) -> Message {
    Message::text(value.to_string())
}

/// How a status speaks: 0 info, 1 warning, 2 error.
#[derive(Debug, Clone, Copy)]
pub(super) enum StatusLevel {
    Info = 0,
    Warning = 1,
    Error = 2,
}

pub(super) fn status(level: StatusLevel, message: &str) -> Message {
    text(json!({"op": "status", "level": level as u8, "message": message}))
}

/// The server's name and what it can do; `session` is one per Host start,
/// so a client that reconnects to the same Host keeps what it has.
pub(super) fn server_info(session: &str) -> Message {
    text(json!({
        "op": "serverInfo",
        "name": format!("vl host {}", env!("CARGO_PKG_VERSION")),
        "capabilities": ["clientPublish", "services", "time"],
        "supportedEncodings": ["json"],
        "metadata": {"lab": "vl", "units": "m (3D), mm (vl.*)"},
        "sessionId": session,
    }))
}

pub(super) fn advertise() -> Message {
    let channels: Vec<Value> = CHANNELS
        .iter()
        .enumerate()
        .map(|(id, topic)| {
            let schema = topic.schema();
            json!({
                "id": id,
                "topic": topic.name(),
                "encoding": "json",
                "schemaName": schema.name,
                "schema": schema.body.to_string(),
                "schemaEncoding": "jsonschema",
            })
        })
        .collect();
    text(json!({"op": "advertise", "channels": channels}))
}

/// Message data: opcode, subscription id, log time, payload.
pub(super) fn data(subscription: u32, view: &View) -> Message {
    let mut bytes = Vec::with_capacity(13 + view.data.len());
    bytes.push(MESSAGE_DATA);
    bytes.extend_from_slice(&subscription.to_le_bytes());
    bytes.extend_from_slice(&view.ns.to_le_bytes());
    bytes.extend_from_slice(&view.data);
    Message::Binary(Bytes::from(bytes))
}

/// The server's time, ns since 1970.
pub(super) fn time(ns: u64) -> Message {
    let mut bytes = Vec::with_capacity(9);
    bytes.push(TIME);
    bytes.extend_from_slice(&ns.to_le_bytes());
    Message::Binary(Bytes::from(bytes))
}

pub(super) fn service_response(call: &ServiceCall, payload: &Value) -> Message {
    let encoding = b"json";
    let payload = payload.to_string();
    let mut bytes = Vec::with_capacity(17 + payload.len());
    bytes.push(SERVICE_CALL_RESPONSE);
    bytes.extend_from_slice(&call.service.to_le_bytes());
    bytes.extend_from_slice(&call.call.to_le_bytes());
    bytes.extend_from_slice(&(encoding.len() as u32).to_le_bytes());
    bytes.extend_from_slice(encoding);
    bytes.extend_from_slice(payload.as_bytes());
    Message::Binary(Bytes::from(bytes))
}

pub(super) fn service_failure(call: &ServiceCall, message: &str) -> Message {
    text(json!({
        "op": "serviceCallFailure",
        "serviceId": call.service,
        "callId": call.call,
        "message": message,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_channel_is_advertised_once_with_its_schema() {
        let Message::Text(json) = advertise() else {
            panic!("advertise is text")
        };
        let value: Value = serde_json::from_str(json.as_str()).unwrap();
        let channels = value["channels"].as_array().unwrap();
        assert_eq!(channels.len(), CHANNELS.len());
        for (id, channel) in channels.iter().enumerate() {
            assert_eq!(channel["id"], id);
            let schema: Value = serde_json::from_str(channel["schema"].as_str().unwrap()).unwrap();
            assert!(schema["properties"].is_object(), "{channel}");
        }
    }

    #[test]
    fn message_data_is_opcode_subscription_time_payload() {
        let view = View {
            topic: Topic::Pose,
            ns: 0x0102_0304_0506_0708,
            data: b"{}".to_vec(),
        };
        let Message::Binary(bytes) = data(7, &view) else {
            panic!("message data is binary")
        };
        assert_eq!(bytes[0], 1);
        assert_eq!(&bytes[1..5], &7u32.to_le_bytes());
        assert_eq!(&bytes[5..13], &view.ns.to_le_bytes());
        assert_eq!(&bytes[13..], b"{}");
    }

    proptest::proptest! {
        /// Whatever bytes a client sends, reading them as a call or a
        /// message on its channel answers, never panics, and takes no
        /// more than was sent.
        #[test]
        fn any_bytes_are_read_or_refused(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..64)) {
            let bytes = Bytes::from(bytes);
            if let Some(call) = ServiceCall::parse(&bytes) {
                proptest::prop_assert!(13 + call.encoding.len() + call.payload.len() == bytes.len());
            }
            if let Some((_, payload)) = client_data(&bytes) {
                proptest::prop_assert_eq!(payload.len() + 5, bytes.len());
            }
        }
    }

    #[test]
    fn a_service_call_is_read_and_a_short_one_refused() {
        let mut bytes = vec![SERVICE_CALL_REQUEST];
        bytes.extend_from_slice(&3u32.to_le_bytes());
        bytes.extend_from_slice(&9u32.to_le_bytes());
        bytes.extend_from_slice(&4u32.to_le_bytes());
        bytes.extend_from_slice(b"json{}");
        let call = ServiceCall::parse(&Bytes::from(bytes.clone())).unwrap();
        assert_eq!(
            (call.service, call.call, call.encoding.as_str()),
            (3, 9, "json")
        );
        assert_eq!(&call.payload[..], b"{}");
        bytes[9] = 200;
        assert!(ServiceCall::parse(&Bytes::from(bytes)).is_none());
        assert!(ServiceCall::parse(&Bytes::from_static(&[2, 0, 0])).is_none());
    }
}
