//! Many cells behind one gateway, on Zenoh, driven from outside: a
//! gateway and three cells as `vl` processes on loopback, each cell with
//! the credentials `vl gateway issue` wrote for it; an outside Zenoh
//! client (Python's `eclipse-zenoh`, nothing of vl's) is kept off the
//! network without them, and with a member's gets nothing of the others'
//! keys; three headless Guests at once through the gateway's
//! one address each get a cell and reach the goal; 150 watchers of the
//! gateway cost the cells next to nothing; a frozen cell leaves within 2 s
//! and comes back; a cell killed with -9 leaves `/status` at once, its
//! watchers told why, and the next Guest still reaches the goal; operators
//! wait in one line for all the cells.

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

use crate::alone;
use crate::common::cells::{Keys, start_cell, start_gateway, start_gateway_on, start_gateway_with};
use crate::common::peer::Peer;
use crate::common::{self, VlProcess};

/// The gateway's `GET /status`.
fn status(url: &str) -> Value {
    status_as(url, None)
}

/// The gateway's `GET /status`, as an administrator (`user:password`).
fn status_as(url: &str, credentials: Option<&str>) -> Value {
    use base64::Engine;
    use std::io::{Read, Write};
    let authority = url.trim_start_matches("ws://").trim_end_matches('/');
    let authorization = credentials.map_or(String::new(), |c| {
        let encoded = base64::engine::general_purpose::STANDARD.encode(c);
        format!("Authorization: Basic {encoded}\r\n")
    });
    let mut tcp = std::net::TcpStream::connect(authority).unwrap();
    write!(
        tcp,
        "GET /status HTTP/1.1\r\nHost: {authority}\r\n{authorization}\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    tcp.read_to_string(&mut answer).unwrap();
    let (_, body) = answer.split_once("\r\n\r\n").unwrap();
    serde_json::from_str(body).unwrap_or_else(|e| panic!("/status is no JSON ({e}): {body}"))
}

fn cell_names(status: &Value) -> Vec<String> {
    status["cells"]
        .as_array()
        .expect("/status lists cells")
        .iter()
        .map(|c| c["name"].as_str().unwrap().to_owned())
        .collect()
}

/// How long until `/status` lists exactly `names`; panics past `within`.
fn until_cells(url: &str, names: &[&str], within: Duration) -> Duration {
    until_cells_as(url, None, names, within)
}

fn until_cells_as(url: &str, admin: Option<&str>, names: &[&str], within: Duration) -> Duration {
    let began = Instant::now();
    loop {
        let listed = cell_names(&status_as(url, admin));
        if listed == names {
            return began.elapsed();
        }
        assert!(
            began.elapsed() < within,
            "/status lists {listed:?}, not {names:?}, after {within:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Until every cell is ready and runs nothing (a minute at most).
fn until_idle(url: &str) {
    let began = Instant::now();
    loop {
        let now = status(url);
        let idle = |c: &Value| c["run"].is_null() && c["lab"] == "ready";
        if now["cells"].as_array().unwrap().iter().all(idle) {
            return;
        }
        assert!(
            began.elapsed() < Duration::from_secs(60),
            "the cells never got ready: {now}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Someone else on the gateway's network (`tests/gateway/outside.py`):
/// what they got, and the process, which stays on the network until
/// dropped.
fn outside(
    zenoh: &str,
    credentials: Option<&Path>,
    info: Option<&Path>,
) -> Option<(Value, Outside)> {
    use std::io::{BufRead, BufReader};
    let python = common::python_with("zenoh")?;
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/gateway/outside.py");
    let mut command = Command::new(python);
    command.arg(script).arg(zenoh);
    command.args(credentials.into_iter().chain(info));
    let mut child = command
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let got = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line:?}"));
    Some((got, Outside(child)))
}

/// The outside client's process, let go when dropped.
struct Outside(std::process::Child);

impl Drop for Outside {
    /// Its stdin closed, it closes its sessions and ends (over QUIC, a
    /// peer killed outright is only given up after its lease); killed if
    /// it has not within 5 s.
    fn drop(&mut self) {
        drop(self.0.stdin.take());
        let began = Instant::now();
        while began.elapsed() < Duration::from_secs(5) {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Processor seconds `pid` has used.
fn cpu_seconds(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    // utime and stime, the 14th and 15th fields, after the command's ')'.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .unwrap()
        .1
        .split_whitespace()
        .collect();
    let ticks: f64 = fields[11].parse::<f64>().unwrap() + fields[12].parse::<f64>().unwrap();
    ticks / 100.0
}

/// The cores `cells` use together over `span`.
fn cores_used(cells: &[&VlProcess], span: Duration) -> f64 {
    let used = |cells: &[&VlProcess]| -> f64 { cells.iter().map(|c| cpu_seconds(c.0.id())).sum() };
    let before = used(cells);
    std::thread::sleep(span);
    (used(cells) - before) / span.as_secs_f64()
}

/// A watcher of the gateway: says hello as an observer and reads all,
/// counted in `seeing` once its first frame came.
async fn watcher(url: String, seeing: Arc<AtomicUsize>) -> tokio::task::JoinHandle<()> {
    let (mut ws, _) = tokio_tungstenite::connect_async(&url)
        .await
        .expect("connects");
    let hello = json!({"type": "hello", "protocol": 1, "role": "observer"});
    ws.send(Message::text(hello.to_string())).await.unwrap();
    // Welcomed before the next comes: a class arrives over seconds, and
    // the gateway keeps at most 64 of one address waiting for a welcome.
    while let Some(Ok(message)) = ws.next().await {
        if let Message::Text(text) = message
            && serde_json::from_str::<Value>(&text).unwrap()["type"] == "welcome"
        {
            break;
        }
    }
    tokio::spawn(async move {
        let mut frames = 0;
        while let Some(Ok(message)) = ws.next().await {
            match message {
                Message::Text(text) => {
                    let v: Value = serde_json::from_str(&text).unwrap();
                    if v["type"] == "ping" {
                        let pong = json!({"type": "pong", "t": v["t"]}).to_string();
                        if ws.send(Message::text(pong)).await.is_err() {
                            break;
                        }
                    }
                }
                Message::Binary(_) => {
                    frames += 1;
                    if frames == 1 {
                        seeing.fetch_add(1, Ordering::Relaxed);
                    }
                }
                _ => {}
            }
        }
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gateway_serves_three_cells_and_outlives_one() {
    let _alone = alone().await;
    let keys = Keys::new("three");
    let names = ["a", "b", "c"];
    let credentials = keys.cells(&names);
    let (_gateway, url, zenoh) = start_gateway(&keys);
    let cells: Vec<VlProcess> = names
        .iter()
        .zip(&credentials)
        .map(|(n, c)| start_cell(&zenoh, n, c))
        .collect();
    let took = until_cells(&url, &names, Duration::from_secs(30));
    eprintln!("the three cells are listed after {took:?}");

    // Three operators at once through the one address: a cell each.
    let runs: Vec<_> = (0..3)
        .map(|_| {
            let url = url.clone();
            std::thread::spawn(move || common::headless_run(&url, 90, &[]))
        })
        .collect();
    // Each operator has a cell of their own, all three at once.
    let began = Instant::now();
    loop {
        let during = status(&url);
        let cells = during["cells"].as_array().unwrap();
        if cells.iter().all(|c| !c["operator"].is_null()) {
            break;
        }
        assert!(began.elapsed() < Duration::from_secs(20), "{during}");
        std::thread::sleep(Duration::from_millis(100));
    }
    for run in runs {
        let report = run.join().unwrap();
        assert_eq!(report["reached_goal"], true, "{report}");
        assert_eq!(report["collisions"], 0, "{report}");
    }

    let watchers = a_class_watches(&url, &cells).await;

    // A cell that falls silent (frozen, or its cable out) leaves after
    // Zenoh's lease (3 s), within twice that, and is back when it answers
    // again.
    let signal = |signal: &str, cell: &VlProcess| {
        let pid = cell.0.id().to_string();
        assert!(
            Command::new("kill")
                .args([signal, &pid])
                .status()
                .unwrap()
                .success()
        );
    };
    signal("-STOP", &cells[2]);
    let silent = until_cells(&url, &["a", "b"], Duration::from_secs(6));
    signal("-CONT", &cells[2]);
    eprintln!("a frozen cell left /status after {silent:?}");
    until_cells(&url, &["a", "b", "c"], Duration::from_secs(10));

    // A watcher of cell b, asked by name, is told when b dies.
    let mut of_b = Peer::connect(&format!("{url}/cells/b")).await;
    of_b.hello("observer").await;
    let mut cells = cells;
    let mut b = cells.remove(1);
    b.0.kill().unwrap();
    let _ = b.0.wait();
    let gone = until_cells(&url, &["a", "c"], Duration::from_secs(4));
    eprintln!("cell b left /status {gone:?} after kill -9");
    of_b.expect_error("cell_lost").await;
    for watcher in watchers {
        watcher.abort();
    }
    let next = common::headless_run(&url, 90, &[]);
    assert_eq!(next["reached_goal"], true, "{next}");
}

/// 150 watchers of the gateway: the cells send each frame once. A cell
/// watched by no one makes no frames; the first Guest on it, at the
/// gateway as at a Host alone, costs its camera's frames. So each cell
/// has one watcher first, then 150 more come. (Once the robots are back
/// at their starts: driving there costs more.) The watchers, still reading.
async fn a_class_watches(url: &str, cells: &[VlProcess]) -> Vec<tokio::task::JoinHandle<()>> {
    until_idle(url);
    let mut watchers = Vec::new();
    let seeing = Arc::new(AtomicUsize::new(0));
    for name in ["a", "b", "c"] {
        watchers.push(watcher(format!("{url}/cells/{name}"), seeing.clone()).await);
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let cell_refs: Vec<&VlProcess> = cells.iter().collect();
    let quiet = cores_used(&cell_refs, Duration::from_secs(6));
    for _ in 0..150 {
        watchers.push(watcher(url.to_owned(), seeing.clone()).await);
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let watched = cores_used(&cell_refs, Duration::from_secs(6));
    // A watcher this test's own two threads cannot keep reading is let go
    // by the gateway, as any that does not read is: counted are those
    // still connected, and nearly all are.
    let connected = || watchers.iter().filter(|w| !w.is_finished()).count() as u64;
    let before = connected();
    let counted: u64 = status(url)["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["watchers"].as_u64().unwrap())
        .sum();
    let after = connected();
    eprintln!(
        "the cells use {quiet:.3} cores with a watcher each, {watched:.3} with {counted} at the gateway ({after} of 153 still connected)"
    );
    assert!(
        (after..=before).contains(&counted),
        "every watcher connected is counted at its cell: {counted}, {after}–{before} connected"
    );
    assert!(
        after >= 145,
        "the gateway let go of {} of 153 watchers",
        153 - after
    );
    assert_eq!(
        seeing.load(Ordering::Relaxed),
        153,
        "every watcher sees the camera"
    );
    assert!(
        watched - quiet <= 0.15,
        "150 watchers cost the cells {:.3} cores",
        watched - quiet
    );
    watchers
}

/// Someone saying hello as operator at `url` (a cell's) every 100 ms
/// until told to stop: how often they were welcomed.
fn pushy(
    url: String,
) -> (
    tokio::sync::watch::Sender<bool>,
    tokio::task::JoinHandle<u32>,
) {
    let (stop_tx, stop) = tokio::sync::watch::channel(false);
    let pushing = tokio::spawn(async move {
        let mut welcomed = 0;
        while !*stop.borrow() {
            let mut peer = Peer::connect(&url).await;
            peer.send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
                .await;
            if let Some(told) = peer
                .next_of_any(&["welcome", "error"], Duration::from_secs(2))
                .await
                && told["type"] == "welcome"
            {
                welcomed += 1;
            }
            peer.send(json!({"type": "bye"})).await;
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        welcomed
    });
    (stop_tx, pushing)
}

/// Strangers do not join the network at `zenoh`: without a certificate,
/// over plain TCP, or with another authority's certificate (`foreign`).
fn strangers_do_not_join(zenoh: &str, foreign: &Path) {
    let plain = zenoh.replace("quic/", "tcp/");
    for (who, endpoint, credentials) in [
        ("no certificate", zenoh, None),
        ("no certificates, over TCP", &plain, None),
        ("another authority's certificate", zenoh, Some(foreign)),
    ] {
        let (got, _) = outside(endpoint, credentials, None).unwrap();
        assert_eq!(got["joined"], false, "a stranger with {who} joined: {got}");
    }
}

/// Ctrl-C stops `gateway` within 2 s.
fn stops_on_ctrl_c(mut gateway: VlProcess) {
    let pid = gateway.0.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-INT", &pid])
            .status()
            .unwrap()
            .success()
    );
    let asked = Instant::now();
    while gateway.0.try_wait().unwrap().is_none() {
        assert!(
            asked.elapsed() < Duration::from_secs(2),
            "the gateway still runs 2 s after Ctrl-C"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    eprintln!("the gateway stopped {:?} after Ctrl-C", asked.elapsed());
}

/// Operators wait in one line for all the cells, and the first cell free
/// is the first in line's; a gateway restarted finds its cells again;
/// careless asks get clear refusals.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn operators_wait_in_one_line_for_every_cell() {
    let _alone = alone().await;
    let keys = Keys::new("line");
    let credentials = keys.cells(&["x", "y"]);
    let (gateway, url, zenoh) = start_gateway(&keys);
    let _cells: Vec<VlProcess> = ["x", "y"]
        .iter()
        .zip(&credentials)
        .map(|(n, c)| start_cell(&zenoh, n, c))
        .collect();
    until_cells(&url, &["x", "y"], Duration::from_secs(30));

    // Asking for a cell that is not there, or by no cell's name.
    let mut lost = Peer::connect(&format!("{url}/cells/z")).await;
    lost.send(json!({"type": "hello", "protocol": 1, "role": "observer"}))
        .await;
    lost.expect_error("no_cell").await;
    let mut careless = Peer::connect(&format!("{url}/cells/NOT%20ONE")).await;
    careless
        .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
        .await;
    careless.expect_error("no_cell").await;

    // Two operators take the two cells; a third is told to wait.
    let mut first = Peer::connect(&url).await;
    first.hello("operator").await;
    let mut second = Peer::connect(&url).await;
    second.hello("operator").await;
    let mut third = Peer::connect(&url).await;
    third
        .send(json!({"type": "hello", "protocol": 1, "role": "operator"}))
        .await;
    third.expect_error("operator_taken").await;
    let welcome = third.hello("observer").await;
    assert!(
        welcome["scene"].is_object(),
        "a watcher sees its cell's lab: {welcome}"
    );
    third
        .send(json!({"type": "mount", "experiment": "teleoperation"}))
        .await;
    third.expect_error("not_allowed_now").await;
    third.send(json!({"type": "queue"})).await;
    let place = third.expect("queue").await;
    assert_eq!(place["position"], 1, "{place}");

    // Someone naming a cell as operator every 100 ms passes no one.
    let (stop_tx, pushy) = pushy(format!("{url}/cells/x"));
    tokio::time::sleep(Duration::from_millis(300)).await;

    // The first leaves: its cell is the third's, who drives there.
    first.send(json!({"type": "bye"})).await;
    let granted = third
        .next_of("role", Duration::from_secs(10))
        .await
        .expect("control within 10 s of a cell coming free");
    assert_eq!(granted["role"], "operator", "{granted}");
    stop_tx.send(true).unwrap();
    assert_eq!(
        pushy.await.unwrap(),
        0,
        "a hello naming the cell took it ahead of the line"
    );
    third.start("teleoperation").await;
    let moved = third.command(1, json!({"v": 40.0, "w": 0.0})).await;
    assert_eq!(moved["type"], "feedback", "{moved}");
    // Both cells driven, no one waiting (the cells tell the gateway how
    // they are twice a second).
    let began = Instant::now();
    loop {
        let now = status(&url);
        let cells = now["cells"].as_array().unwrap();
        if cells.iter().all(|c| !c["operator"].is_null()) && now["line"] == json!([]) {
            break;
        }
        assert!(began.elapsed() < Duration::from_secs(3), "{now}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    // A gateway restarted on the same router address finds its cells
    // again by itself.
    drop(gateway);
    let (_again, url) = start_gateway_on(&keys, &zenoh, &[]);
    let back = until_cells(&url, &["x", "y"], Duration::from_secs(15));
    eprintln!("the cells are back at a restarted gateway after {back:?}");
}

/// The gateway keeps the accounts: a hello logs in there (a wrong password
/// gets nowhere near a cell), and an account removed while its person
/// drives a cell through the gateway is let go within seconds, its cell
/// freed; others keep watching.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_gateway_keeps_the_accounts() {
    let _alone = alone().await;
    let dir = common::scratch("gateway-accounts");
    let file = dir.join("users.toml");
    let file = common::s(&file);
    common::account(file.as_ref(), "ada", "operator", "correct horse");
    common::account(file.as_ref(), "bob", "observer", "battery staple");
    common::account(file.as_ref(), "root", "admin", "root password");
    let admin = Some("root:root password");
    let keys = Keys::new("accounts");
    let solo = keys.issue("--cell", "solo");
    let (_gateway, url, zenoh) = start_gateway_with(&keys, &["--users", file]);
    let _cell = start_cell(&zenoh, "solo", &solo);
    until_cells_as(&url, admin, &["solo"], Duration::from_secs(30));
    let login = |role: &str, user: &str, password: &str| json!({"type": "hello", "protocol": 1, "role": role, "user": user, "password": password});

    let mut intruder = Peer::connect(&url).await;
    intruder.send(login("operator", "ada", "wrong")).await;
    intruder.expect_error("unauthorized").await;
    let mut bob = Peer::connect(&url).await;
    bob.send(login("operator", "bob", "battery staple")).await;
    bob.expect_error("unauthorized").await;
    bob.send(login("observer", "bob", "battery staple")).await;
    assert_eq!(bob.expect("welcome").await["user"], "bob");

    let mut ada = Peer::connect(&url).await;
    ada.send(login("operator", "ada", "correct horse")).await;
    let welcome = ada.expect("welcome").await;
    assert_eq!(
        welcome["user"], "ada",
        "the cell knows who the gateway let in: {welcome}"
    );
    ada.start("teleoperation").await;
    // One place per account: ada's second connection may not wait too.
    let mut again = Peer::connect(&url).await;
    again.send(login("observer", "ada", "correct horse")).await;
    again.expect("welcome").await;
    again.send(json!({"type": "queue"})).await;
    let refused = again.expect_error("not_allowed_now").await;
    assert!(
        refused["message"]
            .as_str()
            .unwrap()
            .contains("one place per account"),
        "{refused}"
    );
    again.send(json!({"type": "bye"})).await;
    // The cells tell the gateway how they are twice a second.
    let began = Instant::now();
    while status_as(&url, admin)["cells"][0]["operator"]["user"] != "ada" {
        assert!(
            began.elapsed() < Duration::from_secs(3),
            "ada drives, yet /status does not say so"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    let out = common::vl(&["users", "remove", file, "ada"]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let removed = Instant::now();
    let ended = ada.expect_error("unauthorized").await;
    assert!(
        ended["message"].as_str().unwrap().contains("removed"),
        "{ended}"
    );
    let done = bob
        .next_of("done", Duration::from_secs(5))
        .await
        .expect("the run ends");
    assert!(
        removed.elapsed() < Duration::from_secs(4),
        "{:?}",
        removed.elapsed()
    );
    eprintln!(
        "ada's run ended {:?} after her account went: {}",
        removed.elapsed(),
        done["summary"]["reason"]
    );
    let began = Instant::now();
    while !status_as(&url, admin)["cells"][0]["operator"].is_null() {
        assert!(
            began.elapsed() < Duration::from_secs(5),
            "the cell is still ada's"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    bob.send(json!({"type": "ping", "t": 1.0})).await;
    bob.expect("pong").await;
}

/// The gateway's Zenoh network is nobody else's: a stranger without a
/// certificate, or with another authority's, does not join; a member (a
/// cell the gateway issued to) reads none of the others' keys, cannot
/// speak for cell a (a hello as the lab's administrator, a phishing
/// message, a 9 MB frame, a forged info) nor for cells that are not
/// (rogue tokens), and speaks only for itself; a cell with another's
/// credentials does not start; a member revoked gets nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn strangers_and_members_get_nothing_of_others() {
    let _alone = alone().await;
    let keys = Keys::new("strangers");
    let a = keys.issue("--cell", "a");
    let b = keys.issue("--cell", "b");
    let evil = keys.issue("--cell", "evil");
    let gone = keys.issue("--cell", "gone");
    let out = common::vl(&["gateway", "revoke", "--cell", "gone", "--keys", keys.dir()]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let elsewhere = Keys::new("strangers-elsewhere");
    let foreign = elsewhere.issue("--cell", "a");

    // A cell given another's credentials says so and does not start.
    let (gateway, url, zenoh) = start_gateway(&keys);
    let out = common::vl(&[
        "host",
        "--listen",
        "127.0.0.1:0",
        "--no-record",
        "--gateway",
        &zenoh,
        "--cell",
        "c",
        "--zenoh-credentials",
        common::s(&a),
    ]);
    assert!(!out.status.success());
    assert!(
        common::stderr(&out).contains("are cell a's, not cell c's"),
        "{}",
        common::stderr(&out)
    );
    let _cells = [start_cell(&zenoh, "a", &a), start_cell(&zenoh, "b", &b)];
    until_cells(&url, &["a", "b"], Duration::from_secs(30));

    if common::python_with("zenoh").is_none() {
        return;
    }
    strangers_do_not_join(&zenoh, &foreign);

    // A student drives cell a through the gateway; b is free; a watcher
    // watches a.
    let mut student = Peer::connect(&format!("{url}/cells/a")).await;
    student.hello("operator").await;
    student.start("teleoperation").await;
    let mut watcher = Peer::connect(&format!("{url}/cells/a")).await;
    watcher.hello("observer").await;

    // A member, as hostile as it can be, for 3 s while the student drives.
    let info = keys.0.join("evil-info.json");
    let mut own: Value = status(&url)["cells"][1].clone();
    own["name"] = json!("evil");
    own.as_object_mut().unwrap().remove("watchers");
    std::fs::write(&info, own.to_string()).unwrap();
    let trying = {
        let (zenoh, evil, info) = (zenoh.clone(), evil.clone(), info.clone());
        tokio::task::spawn_blocking(move || outside(&zenoh, Some(&evil), Some(&info)).unwrap())
    };
    let mut event = 0;
    while !trying.is_finished() {
        event += 1;
        let fed = student.command(event, json!({"v": 0.0, "w": 0.3})).await;
        assert_eq!(fed["type"], "feedback", "{fed}");
    }
    let (got, member) = trying.await.unwrap();
    eprintln!("a member's try, the student driving on ({event} commands): {got}");
    assert_eq!(got["joined"], true, "{got}");
    assert_eq!(got["read"], 0, "a member read others' keys: {got}");
    assert_eq!(got["listed"], json!([]), "a member listed the cells: {got}");
    // The control: the member is a cell on its own keys. Nothing else.
    let listed = until_cells(&url, &["a", "b", "evil"], Duration::from_secs(5));
    eprintln!("the member's own cell listed after {listed:?}");
    let now = status(&url);
    let cell = |n: usize| now["cells"][n].clone();
    assert!(
        !cell(0)["operator"].is_null() && cell(0)["operator"]["user"].is_null(),
        "cell a's operator is the student, no administrator: {now}"
    );
    assert!(cell(1)["operator"].is_null(), "cell b is free: {now}");
    assert_eq!(cell(0)["line"], 0, "{now}");
    // The student and the watcher were told nothing forged and still are.
    let fed = student
        .command(event + 1, json!({"v": 0.0, "w": 0.0}))
        .await;
    assert_eq!(fed["type"], "feedback", "{fed}");
    watcher.send(json!({"type": "ping", "t": 2.0})).await;
    let told = watcher
        .next_of_any(&["error", "pong"], Duration::from_secs(5))
        .await
        .expect("the watcher still hears");
    assert_eq!(told["type"], "pong", "the watcher was told {told}");
    drop(member);
    until_cells(&url, &["a", "b"], Duration::from_secs(5));

    // Revoked: it joins (its certificate is still good) but may do nothing.
    let gone_info = keys.0.join("gone-info.json");
    own["name"] = json!("gone");
    std::fs::write(&gone_info, own.to_string()).unwrap();
    let (got, _gone) = outside(&zenoh, Some(&gone), Some(&gone_info)).unwrap();
    assert_eq!(got["read"], 0, "{got}");
    assert_eq!(cell_names(&status(&url)), ["a", "b"]);

    // Ctrl-C stops the gateway within 2 s, cells joined.
    stops_on_ctrl_c(gateway);
}
