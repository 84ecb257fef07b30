//! The `vl.*` channels' schemas: each a message of the protocol (or a
//! number made of one) described from its Rust type, so Foxglove's Plot
//! and Raw Messages see every field, and no schema is kept by hand beside
//! the type it describes.

use serde_json::Value;
use vl_core::{GuestMessage, HostMessage};

use super::foxglove::{Schema, schema_of};

/// The schema of the variant of `T` (an internally tagged enum) whose
/// `"type"` is `kind`.
fn variant<T: schemars::JsonSchema>(name: &'static str, kind: &str, what: &str) -> Schema {
    let whole = schema_of::<T>(name).body;
    let tagged = |schema: &&Value| {
        let tag = &schema["properties"]["type"];
        tag["const"] == kind
            || tag["enum"]
                .as_array()
                .is_some_and(|e| e.len() == 1 && e[0] == kind)
    };
    let mut body = whole["oneOf"]
        .as_array()
        .and_then(|variants| variants.iter().find(tagged))
        .cloned()
        .unwrap_or_else(|| panic!("{name}: the protocol has no message of type {kind}"));
    if let Some(object) = body.as_object_mut() {
        object.insert("title".into(), Value::from(name));
        object.insert(
            "description".into(),
            Value::from(format!(
                "{what}: the message of vl's protocol v1 (docs/protocol.md), as its Guests got it"
            )),
        );
    }
    Schema { name, body }
}

/// A message the Host sends, of type `kind`.
pub(crate) fn sent(name: &'static str, kind: &str, what: &str) -> Schema {
    variant::<HostMessage>(name, kind, what)
}

/// A message a Guest sends, of type `kind`.
pub(crate) fn heard(name: &'static str, kind: &str, what: &str) -> Schema {
    variant::<GuestMessage>(name, kind, what)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_feedback_s_schema_names_its_fields() {
        let schema = sent("vl.Feedback", "feedback", "the robot");
        let properties = &schema.body["properties"];
        for field in ["event", "t_ms", "pose", "wheels", "proximity", "contact"] {
            assert!(properties.get(field).is_some(), "{field}: {}", schema.body);
        }
        assert!(!schema.body.to_string().contains("$ref"));
    }
}
