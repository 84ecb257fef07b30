//! Every example in docs/protocol.md decodes as the message family its
//! code block names, and every message type has an example.

use std::collections::BTreeSet;

use vl_core::{GuestMessage, HostMessage, Wire};

/// The ```json guest / ```json host blocks of the document.
fn examples() -> Vec<(String, String)> {
    let doc = include_str!("../docs/protocol.md");
    let mut blocks = Vec::new();
    let mut current: Option<(String, String)> = None;
    for line in doc.lines() {
        match (&mut current, line.trim()) {
            (None, fence) if fence.starts_with("```json ") => {
                current = Some((fence["```json ".len()..].to_owned(), String::new()));
            }
            (Some(_), "```") => blocks.push(current.take().expect("inside a block")),
            (Some((_, body)), _) => {
                body.push_str(line);
                body.push('\n');
            }
            (None, _) => {}
        }
    }
    blocks
}

#[test]
fn every_documented_example_decodes() {
    let mut guest_kinds = BTreeSet::new();
    let mut host_kinds = BTreeSet::new();
    for (side, body) in examples() {
        match side.as_str() {
            "guest" => {
                let m = GuestMessage::decode(&body).unwrap_or_else(|e| panic!("{e}:\n{body}"));
                guest_kinds.insert(m.kind());
            }
            "host" => {
                let m = HostMessage::decode(&body).unwrap_or_else(|e| panic!("{e}:\n{body}"));
                let kind = serde_json::to_value(&m).unwrap()["type"]
                    .as_str()
                    .unwrap()
                    .to_owned();
                host_kinds.insert(kind);
            }
            other => panic!("a json block names side {other:?}, not guest or host"),
        }
    }
    let expected_guest: BTreeSet<_> = GuestMessage::TYPES.iter().copied().collect();
    assert_eq!(
        guest_kinds, expected_guest,
        "Guest message types without an example"
    );
    let expected_host: BTreeSet<String> =
        HostMessage::TYPES.iter().map(|t| t.to_string()).collect();
    assert_eq!(
        host_kinds, expected_host,
        "Host message types without an example"
    );
}
