//! Many cells behind one gateway, on Zenoh, driven from outside: a
//! gateway and three cells as `vl` processes on loopback; an outside Zenoh
//! client (Python's `eclipse-zenoh`, nothing of vl's) sees the cells'
//! liveliness tokens; three headless Guests at once through the gateway's
//! one address each get a cell and reach the goal; 150 watchers of the
//! gateway cost the cells next to nothing; a frozen cell leaves within 2 s
//! and comes back; a cell killed with -9 leaves `/status` at once, its
//! watchers told why, and the next Guest still reaches the goal; operators
//! wait in one line for all the cells.

use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

use crate::alone;
use crate::common::peer::Peer;
use crate::common::{self, VlProcess, free_port, start_vl};

/// A gateway on a free port, its Zenoh router on another: its URL and
/// the router's endpoint.
fn start_gateway() -> (VlProcess, String, String) {
    let zenoh = format!("tcp/127.0.0.1:{}", free_port());
    let (gateway, url) = start_vl(
        &[
            "gateway",
            "--listen",
            "127.0.0.1:0",
            "--zenoh-listen",
            &zenoh,
        ],
        "vl gateway listening on ",
    );
    (gateway, url, zenoh)
}

/// A simulated cell named `name` joining the gateway at `zenoh`.
fn start_cell(zenoh: &str, name: &str) -> VlProcess {
    let args = [
        "host",
        "--listen",
        "127.0.0.1:0",
        "--no-record",
        "--gateway",
        zenoh,
        "--cell",
        name,
    ];
    start_vl(&args, "vl host listening on ").0
}

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

/// The liveliness tokens under `vl/cells/*` an outside Zenoh client sees.
fn tokens_seen_from_python(zenoh: &str) -> Option<Vec<String>> {
    let python = common::python_with("zenoh")?;
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/gateway/tokens.py");
    let out = Command::new(python).args([script, zenoh]).output().unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    Some(serde_json::from_slice(&out.stdout).expect("the client prints JSON"))
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
    let (_gateway, url, zenoh) = start_gateway();
    let cells: Vec<VlProcess> = ["a", "b", "c"]
        .iter()
        .map(|n| start_cell(&zenoh, n))
        .collect();
    let took = until_cells(&url, &["a", "b", "c"], Duration::from_secs(30));
    eprintln!("the three cells are listed after {took:?}");

    if let Some(tokens) = tokens_seen_from_python(&zenoh) {
        assert_eq!(tokens, ["vl/cells/a", "vl/cells/b", "vl/cells/c"]);
    }

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

    // 150 watchers of the gateway: the cells send each frame once. A cell
    // watched by no one makes no frames; the first Guest on it, at the
    // gateway as at a Host alone, costs its camera's frames. So each cell
    // has one watcher first, then 150 more come. (Once the robots are back
    // at their starts: driving there costs more.)
    until_idle(&url);
    let mut watchers = Vec::new();
    let seeing = Arc::new(AtomicUsize::new(0));
    for name in ["a", "b", "c"] {
        watchers.push(watcher(format!("{url}/cells/{name}"), seeing.clone()).await);
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let cell_refs: Vec<&VlProcess> = cells.iter().collect();
    let quiet = cores_used(&cell_refs, Duration::from_secs(6));
    for _ in 0..150 {
        watchers.push(watcher(url.clone(), seeing.clone()).await);
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let watched = cores_used(&cell_refs, Duration::from_secs(6));
    let counted: u64 = status(&url)["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["watchers"].as_u64().unwrap())
        .sum();
    eprintln!(
        "the cells use {quiet:.3} cores with a watcher each, {watched:.3} with {counted} at the gateway"
    );
    assert_eq!(counted, 153, "every watcher is counted at its cell");
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

    // A cell that falls silent (frozen, or its cable out) leaves within
    // Zenoh's lease, and is back when it answers again.
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
    let silent = until_cells(&url, &["a", "b"], Duration::from_secs(2));
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
    if let Some(tokens) = tokens_seen_from_python(&zenoh) {
        assert_eq!(tokens, ["vl/cells/a", "vl/cells/c"]);
    }
    for watcher in watchers {
        watcher.abort();
    }
    let next = common::headless_run(&url, 90, &[]);
    assert_eq!(next["reached_goal"], true, "{next}");
}

/// Operators wait in one line for all the cells, and the first cell free
/// is the first in line's; a gateway restarted finds its cells again;
/// careless asks get clear refusals.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn operators_wait_in_one_line_for_every_cell() {
    let _alone = alone().await;
    let (gateway, url, zenoh) = start_gateway();
    let _cells: Vec<VlProcess> = ["x", "y"].iter().map(|n| start_cell(&zenoh, n)).collect();
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

    // The first leaves: its cell is the third's, who drives there.
    first.send(json!({"type": "bye"})).await;
    let granted = third
        .next_of("role", Duration::from_secs(10))
        .await
        .expect("control within 10 s of a cell coming free");
    assert_eq!(granted["role"], "operator", "{granted}");
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
    let port = zenoh.rsplit_once(':').unwrap().1;
    let listen = format!("tcp/127.0.0.1:{port}");
    let (_again, url, _) = {
        let (g, u) = start_vl(
            &[
                "gateway",
                "--listen",
                "127.0.0.1:0",
                "--zenoh-listen",
                &listen,
            ],
            "vl gateway listening on ",
        );
        (g, u, ())
    };
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
    let zenoh = format!("tcp/127.0.0.1:{}", free_port());
    let (_gateway, url) = start_vl(
        &[
            "gateway",
            "--listen",
            "127.0.0.1:0",
            "--zenoh-listen",
            &zenoh,
            "--users",
            file,
        ],
        "vl gateway listening on ",
    );
    let _cell = start_cell(&zenoh, "solo");
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
