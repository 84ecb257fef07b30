//! The `vl.*` channels' schemas: each a message of the protocol (or a
//! number made of one) described from its Rust type, so Foxglove's Plot
//! and Raw Messages see every field, and no schema is kept by hand beside
//! the type it describes; and every schema cut to what Foxglove's and
//! Lichtblick's parser reads (`readable`).

use schemars::JsonSchema;
use serde_json::Value;
use vl_core::{GuestMessage, HostMessage};

/// A schema: its name, which Foxglove's panels recognise, and its JSON
/// Schema.
pub struct Schema {
    pub name: &'static str,
    pub body: Value,
}

/// The JSON Schema of `T`, named `name`, with every part written out where
/// it is used (Foxglove's schema parser follows no `$ref`).
pub(crate) fn schema_of<T: JsonSchema>(name: &'static str) -> Schema {
    let settings = schemars::generate::SchemaSettings::draft07().with(|s| {
        s.inline_subschemas = true;
    });
    let mut body = settings
        .into_generator()
        .into_root_schema_for::<T>()
        .to_value();
    if let Some(object) = body.as_object_mut() {
        object.remove("$schema");
        object.insert("title".into(), Value::from(name));
    }
    readable(&mut body);
    Schema { name, body }
}

/// The schema of the variant of `T` (an internally tagged enum) whose
/// `"type"` is `kind`.
fn variant<T: JsonSchema>(name: &'static str, kind: &str, what: &str) -> Schema {
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
    readable(&mut body);
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

/// Rewrites an object's schema into the part of JSON Schema that
/// Foxglove's and Lichtblick's parser reads: each field of one type
/// (boolean, string, number, integer, object, or an array of one of those
/// but arrays), or a choice of numbers. A field that may be null takes its
/// other type; a choice of strings is a string; a choice of objects (a
/// tagged enum) one object with every alternative's fields. What cannot be
/// said so (a choice of a string and an object, an array of arrays) is
/// left out of `properties`: the message still carries it, the panels do
/// not offer it by name.
pub(crate) fn readable(schema: &mut Value) {
    let Some(properties) = schema.get_mut("properties").and_then(Value::as_object_mut) else {
        return;
    };
    properties.retain(|_, field| field_readable(field));
}

/// Makes `field` readable; false when it cannot be.
fn field_readable(field: &mut Value) -> bool {
    simplify(field);
    match field["type"].as_str() {
        Some("object") => {
            readable(field);
            true
        }
        Some("array") => {
            let items = &mut field["items"];
            simplify(items);
            match items["type"].as_str() {
                Some("object") => {
                    readable(items);
                    true
                }
                Some("boolean" | "string" | "number" | "integer") => true,
                _ => false,
            }
        }
        Some("boolean" | "string" | "number" | "integer") => true,
        _ => field["oneOf"]
            .as_array()
            .is_some_and(|choices| choices.iter().all(|c| c["const"].is_number())),
    }
}

/// One type for `field` where it offers several.
fn simplify(field: &mut Value) {
    let Some(object) = field.as_object_mut() else {
        return;
    };
    if let Some(types) = object.get("type").and_then(Value::as_array) {
        let some: Vec<&Value> = types.iter().filter(|t| *t != "null").collect();
        if let [one] = some.as_slice() {
            let one = (*one).clone();
            object.insert("type".into(), one);
        }
    }
    for key in ["anyOf", "oneOf", "allOf"] {
        let Some(Value::Array(choices)) = object.get(key) else {
            continue;
        };
        if choices.iter().all(|c| c["const"].is_number()) {
            continue;
        }
        let choices: Vec<Value> = choices
            .iter()
            .filter(|c| c["type"] != "null")
            .cloned()
            .collect();
        object.remove(key);
        if let Some(Value::Object(merged)) = merge(choices, key == "allOf") {
            for (k, v) in merged {
                object.entry(k).or_insert(v);
            }
        }
    }
    let strings = object.get("const").is_some_and(Value::is_string)
        || object
            .get("enum")
            .and_then(Value::as_array)
            .is_some_and(|e| e.iter().all(Value::is_string));
    if strings && !object.contains_key("type") {
        object.insert("type".into(), Value::from("string"));
    }
}

/// One schema for all of `choices`, if they are all strings or all objects.
fn merge(mut choices: Vec<Value>, all: bool) -> Option<Value> {
    for choice in &mut choices {
        simplify(choice);
    }
    if let [one] = choices.as_slice() {
        return Some(one.clone());
    }
    if choices.iter().all(|c| c["type"] == "string") {
        let values: Vec<Value> = choices
            .iter()
            .flat_map(|c| match (&c["const"], &c["enum"]) {
                (Value::String(s), _) => vec![Value::from(s.as_str())],
                (_, Value::Array(e)) => e.clone(),
                _ => vec![],
            })
            .collect();
        let mut string = serde_json::json!({"type": "string"});
        if !values.is_empty() && values.len() == choices.len() {
            string["enum"] = Value::Array(values);
        }
        return Some(string);
    }
    if choices.iter().all(|c| c["type"] == "object") {
        let mut properties = serde_json::Map::new();
        let mut required = Vec::new();
        for choice in &choices {
            for (k, v) in choice["properties"].as_object().into_iter().flatten() {
                properties.entry(k.clone()).or_insert_with(|| v.clone());
            }
            // Every part of an allOf holds; of a choice, none for sure.
            if all {
                required.extend(choice["required"].as_array().into_iter().flatten().cloned());
            }
        }
        return Some(
            serde_json::json!({"type": "object", "properties": properties, "required": required}),
        );
    }
    None
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

    #[test]
    fn choices_become_one_type_and_what_cannot_is_left_out() {
        let mut schema = serde_json::json!({
            "type": "object",
            "properties": {
                "maybe": {"type": ["number", "null"]},
                "kind": {"oneOf": [{"const": "a", "type": "string"}, {"const": "b", "type": "string"}]},
                "level": {"oneOf": [{"const": 0, "title": "INFO"}, {"const": 1, "title": "WARN"}]},
                "shape": {"oneOf": [
                    {"type": "object", "properties": {"circle": {"type": "number"}}},
                    {"type": "object", "properties": {"square": {"type": "number"}}},
                ]},
                "nearest": {"oneOf": [{"const": "wall", "type": "string"}, {"type": "object", "properties": {}}]},
                "rows": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
                "goal": {"anyOf": [{"type": "object", "properties": {"x": {"type": "number"}}}, {"type": "null"}]},
            }
        });
        readable(&mut schema);
        let p = &schema["properties"];
        assert_eq!(p["maybe"]["type"], "number");
        assert_eq!(p["kind"]["type"], "string");
        assert_eq!(p["kind"]["enum"], serde_json::json!(["a", "b"]));
        assert!(p["level"]["oneOf"].is_array(), "a choice of numbers stays");
        assert_eq!(p["shape"]["type"], "object");
        assert!(p["shape"]["properties"]["square"].is_object());
        assert_eq!(p["goal"]["properties"]["x"]["type"], "number");
        assert!(
            p.get("nearest").is_none() && p.get("rows").is_none(),
            "{schema}"
        );
    }
}
