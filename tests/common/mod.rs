//! What the integration tests share: running `vl` as a user would, keeping
//! long-running `vl` processes (a Host, the Khepera emulator) alive for a
//! test and killing them however it ends, and scratch directories.

pub(crate) mod cells;
pub(crate) mod chromium;
pub(crate) mod peer;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// The `vl` binary under test.
pub(crate) fn vl_bin() -> &'static str {
    env!("CARGO_BIN_EXE_vl")
}

/// `vl`, its recordings (a Host records every run in the user's data
/// directory) kept under the build's scratch space, not the user's.
pub(crate) fn vl_command() -> Command {
    let mut command = Command::new(vl_bin());
    command.env(
        "XDG_DATA_HOME",
        Path::new(env!("CARGO_TARGET_TMPDIR")).join("xdg-data"),
    );
    command
}

/// Runs `vl ARGS…` to the end with no display, as on a headless machine.
pub(crate) fn vl(args: &[&str]) -> Output {
    vl_command()
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("vl runs")
}

pub(crate) fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `vl ARGS…`, which must succeed, and parses its stdout as JSON.
pub(crate) fn vl_json(args: &[&str]) -> serde_json::Value {
    let out = vl(args);
    assert!(
        out.status.success(),
        "vl {args:?} exited {:?}: {}",
        out.status,
        stderr(&out)
    );
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("vl {args:?} printed no JSON ({e}): {}", stdout(&out)))
}

/// A headless operator's whole run on `url` (given up after `timeout_s`)
/// as its JSON report, whether or not it reached the goal.
pub(crate) fn headless_run(url: &str, timeout_s: u32, extra: &[&str]) -> serde_json::Value {
    let out = headless(url, timeout_s, extra);
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "vl guest --headless {extra:?} printed no report ({e}): {}{}",
            stdout(&out),
            stderr(&out)
        )
    })
}

/// `vl guest --headless --json` on `url` (given up after `timeout_s`)
/// with `extra` arguments, as it ended.
pub(crate) fn headless(url: &str, timeout_s: u32, extra: &[&str]) -> Output {
    let timeout = timeout_s.to_string();
    let args = [
        "guest",
        "--connect",
        url,
        "--headless",
        "--json",
        "--timeout",
        &timeout,
    ];
    vl(&[&args, extra].concat())
}

/// Runs `vl ARGS…`, which must refuse with exit code 2 and say `needle`.
pub(crate) fn refused(args: &[&str], needle: &str) {
    let out = vl(args);
    assert_eq!(out.status.code(), Some(2), "vl {args:?}: {}", stderr(&out));
    assert!(
        stderr(&out).contains(needle),
        "vl {args:?} should say {needle:?}: {}",
        stderr(&out)
    );
    assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
}

/// A `vl` process that is killed when the test ends, pass or fail.
pub(crate) struct VlProcess(pub Child);

impl Drop for VlProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `vl ARGS…` (in `dir`, if given) and returns it with the end of
/// its first line after `prefix`: where it listens, or its device.
pub(crate) fn start_vl_in(dir: Option<&Path>, args: &[&str], prefix: &str) -> (VlProcess, String) {
    let mut command = vl_command();
    command.args(args).stdout(Stdio::piped());
    if let Some(dir) = dir {
        command.current_dir(dir);
    }
    let mut child = command.spawn().expect("vl starts");
    let stdout = child.stdout.take().expect("piped stdout");
    let process = VlProcess(child);
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("vl prints its first line");
    let rest = line
        .trim()
        .strip_prefix(prefix)
        .unwrap_or_else(|| panic!("vl {args:?}: unexpected first line {line:?}"))
        .to_owned();
    (process, rest)
}

pub(crate) fn start_vl(args: &[&str], prefix: &str) -> (VlProcess, String) {
    start_vl_in(None, args, prefix)
}

/// Starts `vl host` on the simulated lab on a free port; returns its URL.
pub(crate) fn start_host(extra: &[&str]) -> (VlProcess, String) {
    start_host_on(&[&["--robot", "sim"], extra].concat())
}

fn start_host_on(args: &[&str]) -> (VlProcess, String) {
    let args = [&["host", "--listen", "127.0.0.1:0"], args].concat();
    start_vl(&args, "vl host listening on ")
}

/// Starts `vl host` driving the Khepera on serial `device`; returns its URL.
pub(crate) fn start_khepera_host(device: &str) -> (VlProcess, String) {
    start_khepera_host_with(device, &[])
}

/// The same with `extra` arguments.
pub(crate) fn start_khepera_host_with(device: &str, extra: &[&str]) -> (VlProcess, String) {
    start_host_on(&[&["--robot", "khepera", "--port", device], extra].concat())
}

/// Starts `vl media` in front of `upstream` with `profile` (a name or a
/// file) and `extra` arguments; returns its URL.
pub(crate) fn start_media(upstream: &str, profile: &str, extra: &[&str]) -> (VlProcess, String) {
    let args = [
        &[
            "media",
            "--listen",
            "127.0.0.1:0",
            "--upstream",
            upstream,
            "--profile",
            profile,
        ],
        extra,
    ]
    .concat();
    let (process, rest) = start_vl(&args, "vl media listening on ");
    let url = rest.split(' ').next().expect("a URL").to_owned();
    (process, url)
}

/// Starts `vl khepera-emu ARGS…`; returns its pseudo-terminal's device.
pub(crate) fn start_emulator(extra: &[&str]) -> (VlProcess, String) {
    let args = [&["khepera-emu"], extra].concat();
    let (process, rest) = start_vl(&args, "vl khepera-emu: ");
    let device = rest.rsplit(' ').next().expect("a device").to_owned();
    (process, device)
}

/// Starts `vl khepera-emu --truth ARGS…`; returns its device and the
/// emulator's later lines (its robot's true pose and contacts) as they come.
pub(crate) fn start_emulator_watched(
    extra: &[&str],
) -> (VlProcess, String, std::sync::mpsc::Receiver<String>) {
    let args = [&["khepera-emu", "--truth"], extra].concat();
    let mut child = Command::new(vl_bin())
        .args(&args)
        .stdout(Stdio::piped())
        .spawn()
        .expect("vl starts");
    let mut lines = BufReader::new(child.stdout.take().expect("piped stdout")).lines();
    let process = VlProcess(child);
    let first = lines
        .next()
        .and_then(Result::ok)
        .expect("vl khepera-emu prints its device");
    let device = first.rsplit(' ').next().expect("a device").to_owned();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    (process, device, rx)
}

/// A fresh, empty directory for one test's files.
pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

/// A path as the `&str` an argument list wants.
pub(crate) fn s(p: &Path) -> &str {
    p.to_str().expect("scratch paths are UTF-8")
}

/// A Python that imports `modules` (as `import` lists them), if one is here.
/// Says that a test cannot run here because `tool` is missing (`install`
/// says where it comes from). CI sets `VL_REQUIRE_EXTERNAL=1`, and there a
/// missing tool fails the test: a check that did not run is not a pass.
/// Elsewhere the test skips, saying why.
pub(crate) fn missing(tool: &str, install: &str) {
    if std::env::var("VL_REQUIRE_EXTERNAL").is_ok_and(|v| v == "1") {
        panic!("{tool} is missing, and VL_REQUIRE_EXTERNAL=1 requires it: {install}");
    }
    eprintln!("skipped: no {tool} here ({install})");
}

/// A Python that imports `modules`, or `None` (said by [`missing`]).
pub(crate) fn python_with(modules: &str) -> Option<&'static str> {
    let found = python_importing(modules);
    if found.is_none() {
        missing(
            &format!("Python with {modules}"),
            ".ci/run installs python3-websockets, python3-zstandard and mcap from PyPI",
        );
    }
    found
}

fn python_importing(modules: &str) -> Option<&'static str> {
    ["python3", "/usr/bin/python3"].into_iter().find(|python| {
        Command::new(python)
            .args(["-c", &format!("import {modules}")])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// Renders one 640-px overhead frame of the navigation arena into `file`
/// (`vl sim render`, with `extra`).
pub(crate) fn render_arena(file: &Path, extra: &[&str]) {
    let args = [
        &["sim", "render", "--arena", "navigation", "--width", "640"],
        extra,
        &["--output", s(file)],
    ]
    .concat();
    let out = vl(&args);
    assert!(out.status.success(), "vl {args:?}: {}", stderr(&out));
}

/// Adds account `name` with `role` and `password` to the accounts file `users`.
pub(crate) fn account(users: &Path, name: &str, role: &str, password: &str) {
    let out = vl_command()
        .args(["users", "add", s(users), name, "--role", role])
        .env("VL_PASSWORD", password)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
}

/// A port nothing listens on right now.
pub(crate) fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// A UDP port nothing listens on now: a Zenoh router's over QUIC.
pub(crate) fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free UDP port")
        .port()
}

/// A definition's virtual obstacles: one 256-vertex polygon, a disc of `r`
/// mm about (x, y) (its edges within r·(1 − cos(π/256)) of the circle).
pub(crate) fn big_polygon(x: f64, y: f64, r: f64) -> serde_json::Value {
    let points: Vec<serde_json::Value> = (0..256)
        .map(|i| {
            let a = f64::from(i) / 256.0 * std::f64::consts::TAU;
            serde_json::json!({"x_mm": x + r * a.cos(), "y_mm": y + r * a.sin()})
        })
        .collect();
    serde_json::json!([{"shape": "polygon", "points": points}])
}
