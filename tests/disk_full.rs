//! A disk that fills under a Host (issue 43, item 10): its files may grow
//! only so far (`RLIMIT_FSIZE`, as a full disk fails a write); a run's
//! recording stops, kept as far as it went, and no `done` names a file
//! that is not there. Alone: a child forked with a file-size limit beside
//! the many processes the other tests start failed to start there.

use std::os::unix::process::CommandExt;
use std::process::Stdio;

use vl_record::Recording;

use crate::common::peer::Peer;
use crate::common::{self, VlProcess, s, scratch};

/// `vl host ARGS` whose files may grow to `fsize` bytes at most, as on a
/// disk that fills: its URL.
fn host_on_a_small_disk(args: &[&str], fsize: u64) -> (VlProcess, String) {
    let mut command = common::vl_command();
    command
        .args(["host", "--listen", "127.0.0.1:0", "--robot", "sim"])
        .args(args)
        .stdout(Stdio::piped())
        // Not the tests' own stderr: when that is a file (`cargo test >
        // log`), it too is past the limit, and the Host's first line there
        // would fail before it ever listens.
        .stderr(Stdio::null());
    // SAFETY: setrlimit is async-signal-safe, called between fork and exec.
    unsafe {
        command.pre_exec(move || {
            let limit = libc::rlimit {
                rlim_cur: fsize,
                rlim_max: fsize,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = command.spawn().expect("vl starts");
    let stdout = child.stdout.take().unwrap();
    let process = VlProcess(child);
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line).unwrap();
    let url = line.trim().strip_prefix("vl host listening on ").unwrap();
    (process, url.to_owned())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_stops_the_recording_and_no_done_names_a_missing_file() {
    let _alone = crate::alone().await;
    // Room for part of a run: its file is kept as far as it went.
    let dir = scratch("room-full").join("runs");
    let (mut host, url) = host_on_a_small_disk(&["--recordings", s(&dir)], 150_000);
    let mut operator = Peer::connect(&url).await;
    operator.hello("operator").await;
    let done = operator.turn_for(8.0, || {}).await;
    let note = &done["summary"]["recording"];
    let why = note["stopped"].as_str().unwrap_or_else(|| panic!("{done}"));
    assert!(why.contains("the disk is full"), "{why}");
    let kept = Recording::open(&dir.join(note["name"].as_str().unwrap())).unwrap();
    assert!(
        kept.messages.len() > 10,
        "{} messages kept",
        kept.messages.len()
    );
    assert!(host.0.try_wait().unwrap().is_none(), "the Host died");
    // No room for a file's beginning: no `done` names a file, and no empty
    // file or entry is left behind.
    let dir = scratch("room-none").join("runs");
    let (mut host, url) = host_on_a_small_disk(&["--recordings", s(&dir)], 2_000);
    let mut operator = Peer::connect(&url).await;
    operator.hello("operator").await;
    for _ in 0..2 {
        let done = operator.turn_for(2.0, || {}).await;
        assert!(done["summary"]["recording"].is_null(), "{done}");
    }
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.file_name())
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    assert!(host.0.try_wait().unwrap().is_none(), "the Host died");
}
