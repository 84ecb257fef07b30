//! Damaged and crafted recordings never crash what reads them (issue 43,
//! item 12): a real run's file with bytes flipped anywhere reads to its
//! damage, and `vl record info`, `repair` and `export` answer a crafted
//! file (a chunk declaring exabytes, a chunk of a gigabyte of zeros
//! compressed) at once with what they could read.
//!
//! `DAMAGE_CASES` sets how many flipped files the property reads (10,000
//! by default).

use std::io::Read;
use std::path::Path;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use proptest::prelude::*;
use vl_record::Recording;

use crate::common::peer::Peer;
use crate::common::{self, s, scratch, start_host};

/// A real run's file: a Host with its simulated camera, one short
/// teleoperation run.
fn a_run() -> &'static [u8] {
    static RUN: OnceLock<Vec<u8>> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = scratch("damage-run");
        let recordings = dir.join("host");
        let (_host, url) = start_host(&["--recordings", s(&recordings)]);
        let runtime = tokio::runtime::Runtime::new().unwrap();
        let name = runtime.block_on(async {
            let mut operator = Peer::connect(&url).await;
            operator.hello("operator").await;
            operator.start("teleoperation").await;
            for event in 1..=20 {
                operator
                    .command(event, serde_json::json!({"v": 20.0, "w": 0.1}))
                    .await;
                tokio::time::sleep(Duration::from_millis(25)).await;
            }
            operator.send(serde_json::json!({"type": "stop"})).await;
            let done = operator.expect("done").await;
            done["summary"]["recording"]["name"]
                .as_str()
                .expect("recorded")
                .to_owned()
        });
        // The recorder closes the file a moment after the run's `done`.
        let file = recordings.join(name);
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let read = Recording::open(&file);
            if read.as_ref().is_ok_and(|r| r.complete) {
                break;
            }
            assert!(Instant::now() < deadline, "the run's file: {read:?}");
            std::thread::sleep(Duration::from_millis(50));
        }
        std::fs::read(&file).unwrap()
    })
}

fn cases() -> u32 {
    std::env::var("DAMAGE_CASES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(10_000)
}

/// Where to flip: anywhere, or in the file's first or last 4 KiB, where
/// its header, schemas and summary are.
fn place() -> impl Strategy<Value = (u8, prop::sample::Index)> {
    (0u8..3, any::<prop::sample::Index>())
}

fn offset(len: usize, (region, at): (u8, prop::sample::Index)) -> usize {
    let edge = len.min(4096);
    match region {
        0 => at.index(len),
        1 => at.index(edge),
        _ => len - edge + at.index(edge),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn byte_flipped_recordings_read_to_their_damage(
        flips in prop::collection::vec((place(), 1u8..=255), 1..4)
    ) {
        let mut bytes = a_run().to_vec();
        for (at, xor) in flips {
            let i = offset(bytes.len(), at);
            bytes[i] ^= xor;
        }
        if let Ok(recording) = Recording::read(Path::new("flipped.mcap"), &bytes) {
            let _ = recording.info();
            let _ = recording.summary();
            let _ = recording.round_trips();
            let _ = recording.replay();
        }
    }
}

/// An MCAP record: opcode, length, body.
fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![opcode];
    out.extend((body.len() as u64).to_le_bytes());
    out.extend(body);
    out
}

fn string(text: &str) -> Vec<u8> {
    let mut out = (text.len() as u32).to_le_bytes().to_vec();
    out.extend(text.as_bytes());
    out
}

/// A chunk record as the MCAP specification lays it out, declaring
/// `declared` bytes of content.
fn chunk(declared: u64, compressed: &[u8]) -> Vec<u8> {
    let mut body = Vec::new();
    body.extend(0u64.to_le_bytes());
    body.extend(1u64.to_le_bytes());
    body.extend(declared.to_le_bytes());
    body.extend(0u32.to_le_bytes());
    body.extend(string("zstd"));
    body.extend((compressed.len() as u64).to_le_bytes());
    body.extend(compressed);
    record(0x06, &body)
}

/// A file that begins as MCAP does (magic, header) and goes on with `rest`.
fn crafted(rest: &[u8]) -> Vec<u8> {
    let mut file = b"\x89MCAP0\r\n".to_vec();
    file.extend(record(0x01, &[string(""), string("crafted")].concat()));
    file.extend(rest);
    file
}

/// `vl record ARGS` within `limit`: it ends by itself, not by a signal,
/// and without a panic.
fn record_tool(args: &[&str], limit: Duration) -> String {
    let started = Instant::now();
    let out = common::vl_command()
        .arg("record")
        .args(args)
        .output()
        .expect("vl runs");
    let took = started.elapsed();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        common::stderr(&out)
    );
    assert!(out.status.code().is_some(), "killed by a signal: {said}");
    assert!(!said.contains("panicked"), "{said}");
    assert!(took < limit, "vl record {args:?} took {took:?}");
    said
}

#[test]
fn crafted_recordings_are_read_at_once_to_their_damage() {
    let dir = scratch("damage-crafted");
    // A gigabyte of zeros, compressed to a few tens of kilobytes.
    let mut zeros = std::io::repeat(0).take(1 << 30);
    let mut bomb = Vec::new();
    zstd::stream::copy_encode(&mut zeros, &mut bomb, 19).unwrap();
    let files = [
        ("exabytes", chunk(4 << 60, &bomb)),
        ("gigabyte", chunk(1 << 30, &bomb)),
        // Declared within what a chunk may grow to: it decompresses no
        // further than declared.
        ("bomb", chunk(bomb.len() as u64 * 100, &bomb)),
    ];
    for (name, rest) in files {
        let file = dir.join(format!("{name}.mcap"));
        std::fs::write(&file, crafted(&rest)).unwrap();
        let limit = Duration::from_secs(3);
        let info = record_tool(&["info", s(&file)], limit);
        assert!(info.contains("unfinished"), "{info}");
        record_tool(&["repair", s(&file)], limit);
        let out = dir.join(format!("{name}-export"));
        record_tool(&["export", s(&file), "--out", s(&out)], limit);
    }
    // And the real run, flipped in its first chunk's content, through the
    // same tools.
    let mut flipped = a_run().to_vec();
    let middle = flipped.len() / 2;
    flipped[middle] ^= 0x5a;
    let file = dir.join("flipped.mcap");
    std::fs::write(&file, &flipped).unwrap();
    for args in [
        vec!["info", s(&file)],
        vec!["repair", s(&file)],
        vec!["export", s(&file), "--out", s(&dir.join("flipped-export"))],
    ] {
        record_tool(&args, Duration::from_secs(20));
    }
}
