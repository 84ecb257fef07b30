//! The lab on ROS 2, checked from outside with PyPI's `zenoh-ros2-sdk`
//! (rmw_zenoh's wire format in Python, nothing of vl's), offline: it reads
//! its message definitions from the folder vl vendors, never from the
//! network. A Host with `--ros2 --ros2-operator` is discovered with the
//! right types and hashes, streams odometry and images at their rates,
//! serves its map to a late subscriber, and is driven by Twists through
//! the safety layer and the watchdog, garbage on `/cmd_vel` moving nothing
//! out of bounds; `--robot ros2` drives a simulated ROS 2 robot written
//! with the same package to a navigation goal, seeing it through the
//! robot's own ROS 2 camera; a gateway's cells are namespaces of their own.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::alone;
use crate::common::cells::{Keys, start_cell_with, start_gateway};
use crate::common::peer::Peer;
use crate::common::{self, free_port, scratch, start_vl};

/// The vendored definitions, the outside client's registry.
const MSGS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/crates/vl-ros2/ros2-msgs");
const LAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/ros2/lab.py");
const ROBOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/ros2/robot.py");

/// A Python with the outside ROS 2 client, or `None` (said why).
fn python() -> Option<&'static str> {
    common::python_with("zenoh_ros2_sdk, PIL")
}

/// `vl host` on loopback, its Zenoh router at `zenoh`, with `extra`.
fn host_args(zenoh: &str, extra: &[&str]) -> Vec<String> {
    ["host", "--listen", "127.0.0.1:0", "--zenoh-listen", zenoh]
        .iter()
        .chain(extra)
        .map(ToString::to_string)
        .collect()
}

fn start_host(zenoh: &str, extra: &[&str]) -> (common::VlProcess, String) {
    let args = host_args(zenoh, extra);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    start_vl(&args, "vl host listening on ")
}

/// One step of the outside client against the router at `port`.
fn step(python: &str, port: u16, args: &[&str]) -> Value {
    step_with(python, port, args, None)
}

/// One step, as the ROS 2 machine `credentials` name on a gateway's
/// network: the SDK's session configured as rmw_zenoh's is, by
/// `ZENOH_CONFIG_OVERRIDE` (mutual TLS to the gateway's router).
fn step_with(python: &str, port: u16, args: &[&str], credentials: Option<&Path>) -> Value {
    let mut command = Command::new(python);
    command.args([LAB, MSGS, &port.to_string()]).args(args);
    if let Some(file) = credentials {
        use base64::Engine;
        let kept: toml::Table = toml::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
        let pem = |key: &str| {
            base64::engine::general_purpose::STANDARD.encode(kept[key].as_str().unwrap())
        };
        let tls = serde_json::json!({
            "root_ca_certificate_base64": pem("authority"),
            "connect_certificate_base64": pem("certificate"),
            "connect_private_key_base64": pem("key"),
            "enable_mtls": true,
        });
        command.env(
            "ZENOH_CONFIG_OVERRIDE",
            format!("transport/link/tls={tls};connect/endpoints=[\"quic/127.0.0.1:{port}\"]"),
        );
    }
    let out = command.output().expect("python runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().last().unwrap_or_default();
    serde_json::from_str(line).unwrap_or_else(|e| {
        panic!(
            "lab.py {args:?} printed no JSON ({e}): {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

const TYPES: [(&str, &str); 7] = [
    ("/odom", "nav_msgs/msg/Odometry"),
    ("/tf", "tf2_msgs/msg/TFMessage"),
    ("/scan", "sensor_msgs/msg/LaserScan"),
    ("/map", "nav_msgs/msg/OccupancyGrid"),
    (
        "/camera/image_raw/compressed",
        "sensor_msgs/msg/CompressedImage",
    ),
    ("/camera/camera_info", "sensor_msgs/msg/CameraInfo"),
    ("/cmd_vel", "geometry_msgs/msg/Twist"),
];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ros_2_tools_see_and_drive_the_lab() {
    let Some(python) = python() else { return };
    let _alone = alone().await;
    let port = free_port();
    let audit = scratch("ros2-audit").join("audit.jsonl");
    let zenoh = format!("tcp/127.0.0.1:{port}");
    // A lab with accounts: the ROS side drives as the account its staff
    // named, a Guest watches as another.
    let users = audit.with_file_name("users.toml");
    common::account(&users, "ada", "observer", "ada-secret-1");
    common::account(&users, "rosie", "operator", "rosie-secret-1");
    let flags = [
        "--no-record",
        "--ros2",
        "--ros2-operator",
        "--ros2-as",
        "rosie",
        "--users",
        common::s(&users),
        "--audit",
        common::s(&audit),
    ];
    let (_host, url) = start_host(&zenoh, &flags);
    discovered(python, port);
    streamed(python, port);
    driven(python, port, &url).await;
    latched(python, port, &url).await;
    let audit = std::fs::read_to_string(&audit).unwrap();
    assert!(
        audit
            .lines()
            .any(|l| l.contains("\"run_started\"") && l.contains("\"user\":\"rosie\"")),
        "the audit log names the account ROS 2 drives as: {audit}"
    );
}

/// At a lab with accounts, `/cmd_vel` drives as an account that may
/// drive, named: anyone on the ROS 2 network is otherwise no one.
#[test]
fn ros_2_drives_only_as_an_account_that_may() {
    let users = scratch("ros2-as").join("users.toml");
    common::account(&users, "ada", "observer", "ada-secret-1");
    let refused = |extra: &[&str], why: &str| {
        let zenoh = format!("tcp/127.0.0.1:{}", free_port());
        let flags = [
            &["--ros2", "--ros2-operator", "--users", common::s(&users)],
            extra,
        ]
        .concat();
        let out = common::vl(
            &host_args(&zenoh, &flags)
                .iter()
                .map(String::as_str)
                .collect::<Vec<_>>(),
        );
        assert_eq!(out.status.code(), Some(2), "{}", common::stderr(&out));
        assert!(
            common::stderr(&out).contains(why),
            "{}",
            common::stderr(&out)
        );
    };
    refused(&[], "name it (--ros2-as NAME)");
    refused(
        &["--ros2-as", "ada"],
        "account ada is an observer's: it may not drive",
    );
    refused(&["--ros2-as", "nobody"], "no account nobody at this lab");
}

/// Ada, logged in to watch: her connection and its welcome.
async fn ada_watching(url: &str) -> (Peer, Value) {
    let mut ada = Peer::connect(url).await;
    let hello = serde_json::json!({
        "type": "hello", "protocol": 1, "role": "observer", "user": "ada", "password": "ada-secret-1",
    });
    ada.send(hello).await;
    let welcome = ada.expect("welcome").await;
    (ada, welcome)
}

/// A watcher's emergency stop while ROS 2 drives is latched: Twists,
/// even after a quiet second, start nothing and move nothing.
async fn latched(python: &str, port: u16, url: &str) {
    // Watching first: the stop is pressed once the robot has turned for
    // half a second, however long Python takes to start on a busy machine.
    let (mut watcher, _) = ada_watching(url).await;
    let driving = {
        let python = python.to_owned();
        // On the spot: the steps before left it by a wall, facing anywhere.
        std::thread::spawn(move || step(&python, port, &["turn", "3", "1.0"]))
    };
    let turning = |f: &Value| {
        let wheel = |side: &str| f["wheels"][side].as_f64().unwrap_or(0.0);
        wheel("left_mm_s") * wheel("right_mm_s") < 0.0
            && (wheel("left_mm_s") - wheel("right_mm_s")).abs() > 10.0
    };
    tokio::time::timeout(Duration::from_secs(20), async {
        while !turning(
            &watcher
                .next_of("feedback", Duration::from_secs(20))
                .await
                .unwrap(),
        ) {}
    })
    .await
    .expect("the Twists turn the robot");
    tokio::time::sleep(Duration::from_millis(500)).await;
    watcher
        .send(serde_json::json!({"type": "emergency_stop"}))
        .await;
    let done = watcher.expect("done").await;
    assert_eq!(done["summary"]["reason"], "emergency_stop", "{done}");
    let stopped = driving.join().unwrap();
    // How far it turned, rad: the quaternion's z is sin(θ/2).
    let moved = |v: &Value| {
        let heading = |key: &str| {
            2.0 * v[key]["qz"]
                .as_f64()
                .unwrap()
                .atan2(v[key]["qw"].as_f64().unwrap())
        };
        let turned = heading("driven") - heading("start");
        turned.sin().atan2(turned.cos()).abs()
    };
    assert!(
        moved(&stopped) > 0.1,
        "it drove until the emergency stop: {stopped}"
    );
    // Quiet for 1.5 s (the second after an ordinary end), then Twists.
    let again = step(python, port, &["turn", "2", "1.0"]);
    assert!(
        moved(&again) < 0.01,
        "Twists after an emergency stop drove the robot: {again}"
    );
    watcher
        .send(serde_json::json!({"type": "ping", "t": 1.0}))
        .await;
    let told = watcher
        .next_of_any(&["started", "pong"], Duration::from_secs(5))
        .await
        .expect("the watcher hears");
    assert_eq!(told["type"], "pong", "a run started: {told}");
}

/// Every topic with its type, and the hash the outside client computes
/// itself from the .msg files.
fn discovered(python: &str, port: u16) {
    let found = step(python, port, &["discover"]);
    for (topic, ty) in TYPES {
        let seen = &found["topics"][topic];
        assert_eq!(seen["types"], serde_json::json!([ty]), "{topic}: {found}");
        assert_eq!(
            seen["hashes"],
            serde_json::json!([seen["sdk_hash"]]),
            "{topic}: {seen}"
        );
        assert_eq!(
            seen["nodes"],
            serde_json::json!(["vl_host"]),
            "{topic}: {seen}"
        );
    }
    assert_eq!(found["topics"]["/cmd_vel"]["subscribers"], 1);
    assert!(
        found["topics"]["/map"]["qos"][0]
            .as_str()
            .unwrap()
            .starts_with("1:1:"),
        "{found}"
    );
}

/// The streams over 3 s, and the map as a late subscriber gets it.
fn streamed(python: &str, port: u16) {
    let watched = step(python, port, &["watch", "3"]);
    let rate = |topic: &str| watched["rates"][topic].as_f64().unwrap();
    assert!(rate("/odom") >= 20.0, "{watched}");
    assert!(rate("/camera/image_raw/compressed") >= 10.0, "{watched}");
    for topic in ["/tf", "/camera/camera_info", "/scan"] {
        assert!(rate(topic) >= 1.0, "{topic}: {watched}");
    }
    let image = &watched["image"];
    assert_eq!(image["decoded"], "JPEG", "Pillow decodes it: {watched}");
    assert_eq!(image["size"], image["sof_size"], "{watched}");
    assert_eq!(image["size"], watched["camera_info"]["size"], "{watched}");
    let odom = &watched["odom"];
    assert_eq!(
        (odom["frame"].as_str(), odom["child"].as_str()),
        (Some("odom"), Some("base_link"))
    );
    let now = watched["now"].as_f64().unwrap();
    assert!(
        (now - odom["stamp"].as_f64().unwrap()).abs() < 2.0,
        "wall-clock stamps: {watched}"
    );
    let tf = watched["tf"].as_array().unwrap();
    let edge = |parent: &str, child: &str| {
        tf.iter()
            .find(|t| t["parent"] == parent && t["child"] == child)
            .unwrap_or_else(|| panic!("no {parent} → {child} in {watched}"))
    };
    assert_eq!(
        edge("odom", "base_link")["xyz"][0],
        odom["x"],
        "/tf says what /odom says"
    );
    edge("map", "odom");
    assert!(
        edge("map", "camera")["xyz"][2].as_f64().unwrap() > 0.1,
        "the camera is above the floor"
    );

    // A subscriber that joins late still gets the map.
    let map = step(python, port, &["map", "5"]);
    assert!(map["maps"].as_u64().unwrap() >= 1, "{map}");
    assert!(
        map["taken"].as_u64().unwrap() > 0,
        "the map shows obstacles: {map}"
    );
    assert_eq!(map["frame"], "map");
    assert_eq!(map["edge_free"], 0, "the arena's walls are taken: {map}");
}

/// Twists drive; silence stops; a Twist toward a wall for 5 s stops short;
/// garbage on `/cmd_vel` drives nothing out of bounds. An observer counts
/// contacts all the while.
async fn driven(python: &str, port: u16, url: &str) {
    let contacts = Arc::new(AtomicUsize::new(0));
    let (mut observer, welcome) = ada_watching(url).await;
    assert_eq!(welcome["user"], "ada", "{welcome}");
    let counting = contacts.clone();
    let watching = tokio::spawn(async move {
        while let Some(message) = observer.next_any().await {
            if message["type"] == "feedback" && message["contact"] == true {
                counting.fetch_add(1, Ordering::Relaxed);
            }
        }
    });
    let forward = step(python, port, &["drive", "1.5", "0.05"]);
    let x = |key: &str| forward[key]["x"].as_f64().unwrap();
    assert!(
        x("driven") - x("start") > 0.04,
        "Twists at 20 Hz move it: {forward}"
    );
    assert!(
        (x("later") - x("after_silence")).abs() < 0.002,
        "silence stops it: {forward}"
    );
    let wall = step(python, port, &["drive", "5", "0.3"]);
    let wx = |key: &str| wall[key]["x"].as_f64().unwrap();
    assert!(
        wx("driven") - wx("start") > 0.01,
        "it goes toward the wall: {wall}"
    );
    assert!(
        (wx("later") - wx("driven")).abs() < 0.002,
        "held short of the wall: {wall}"
    );
    // A million garbage samples on /cmd_vel's key: the lab keeps its
    // rates, the robot within its limits.
    let hostile = step(python, port, &["hostile", "3"]);
    assert!(hostile["sent"].as_u64().unwrap() > 1000, "{hostile}");
    assert!(
        hostile["odoms"].as_u64().unwrap() >= 60,
        "/odom kept going: {hostile}"
    );
    let fastest = |key: &str| hostile[key].as_f64().unwrap();
    assert!(fastest("fastest_v") <= 1.0, "{hostile}");
    assert!(fastest("fastest_w") <= 50.0, "{hostile}");
    tokio::time::sleep(Duration::from_millis(500)).await;
    watching.abort();
    assert_eq!(contacts.load(Ordering::Relaxed), 0, "no contact, ever");
}

/// The simulated ROS 2 robot, started at the lab's start pose with its
/// overhead camera over `backdrop` (its body stuck once its wheels have
/// rolled `stuck_after_m`, if given), and a thread keeping its last report.
fn start_robot(
    python: &str,
    port: u16,
    backdrop: &std::path::Path,
    stuck_after_m: Option<f64>,
) -> (Child, Arc<std::sync::Mutex<String>>) {
    let mut robot = Command::new(python)
        .args([ROBOT, MSGS, &port.to_string(), "0.1", "0.12", "0"])
        .args([common::s(backdrop), "800"])
        .args(stuck_after_m.map(|m| m.to_string()))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("python runs");
    let said = Arc::new(std::sync::Mutex::new(String::new()));
    let keep = said.clone();
    let stdout = robot.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            *keep.lock().unwrap() = line;
        }
    });
    (robot, said)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_lab_drives_a_ros_2_robot_to_its_goal() {
    let Some(python) = python() else { return };
    let _alone = alone().await;
    let port = free_port();
    // The arena as the camera sees it, which the robot draws itself on.
    let backdrop = scratch("ros2-robot").join("backdrop.png");
    common::render_arena(&backdrop, &[]);
    let (robot, said) = start_robot(python, port, &backdrop, None);
    let _robot = common::VlProcess(robot);
    let zenoh = format!("tcp/127.0.0.1:{port}");
    let recordings = scratch("ros2-recordings");
    let camera = [
        "--robot",
        "ros2",
        "--camera",
        "ros2:/camera/image_raw/compressed",
        "--recordings",
        common::s(&recordings),
    ];
    let (_host, url) = start_host(&zenoh, &camera);
    // A stranger says the robot stands at its start, 400 times a second,
    // through the run: the lab takes its robot's own /odom only.
    let forging = {
        let python = python.to_owned();
        std::thread::spawn(move || step(&python, port, &["forge_odom", "8", "own"]))
    };
    let run_url = url.clone();
    let report = tokio::task::spawn_blocking(move || common::headless_run(&run_url, 90, &[]))
        .await
        .unwrap();
    // Where the robot says it is as the run ends (it is driven back next).
    let last: Value = serde_json::from_str(&said.lock().unwrap()).unwrap();
    let forged = forging.join().unwrap();
    assert!(forged["sent"].as_u64().unwrap() > 1000, "{forged}");
    let summary = &report["summary"];
    assert_eq!(report["reached_goal"], true, "{summary}");
    assert_eq!(summary["collisions"], 0, "{summary}");
    assert_eq!(
        summary["pose_source"], "camera",
        "the ROS 2 camera located it: {summary}"
    );
    assert!(
        report["frames"].as_u64().unwrap() > 10,
        "the Guest saw the ROS 2 camera"
    );
    assert!(
        report["forecast"]["forecast_s"].as_f64().unwrap() > 0.0,
        "the forecast was in the loop"
    );
    assert!(
        last["twists"].as_u64().unwrap() > 50,
        "the robot took the lab's Twists: {last}"
    );
    // The goal is the lab's reading of the robot's own /odom: the robot
    // itself has travelled (it reports its pose once a second).
    let travelled = (last["x"].as_f64().unwrap() - 0.1).hypot(last["y"].as_f64().unwrap() - 0.12);
    assert!(travelled > 0.3, "the robot itself moved: {last}");
    let recorded = std::fs::read_dir(&recordings)
        .unwrap()
        .filter_map(Result::ok)
        .any(|f| f.path().extension().is_some_and(|e| e == "mcap"));
    assert!(recorded, "the run was recorded in {}", recordings.display());
    untrusted_while_forged(python, port, &url).await;
}

/// A robot whose wheels spin while its body is stuck: its own /odom says
/// it goes on, the camera says it does not. The lab believes the camera
/// and stops the run as a fault, saying why; the robot is no longer driven.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn odometry_the_camera_contradicts_stops_the_robot() {
    let Some(python) = python() else { return };
    let _alone = alone().await;
    let port = free_port();
    let backdrop = scratch("ros2-stuck").join("backdrop.png");
    common::render_arena(&backdrop, &[]);
    let (robot, said) = start_robot(python, port, &backdrop, Some(0.08));
    let _robot = common::VlProcess(robot);
    let zenoh = format!("tcp/127.0.0.1:{port}");
    // Not driven back to the start after the run: nothing drives it then.
    let camera = [
        "--robot",
        "ros2",
        "--camera",
        "ros2:/camera/image_raw/compressed",
        "--no-reset",
    ];
    let (_host, url) = start_host(&zenoh, &camera);
    let run_url = url.clone();
    let report = tokio::task::spawn_blocking(move || common::headless_run(&run_url, 90, &[]))
        .await
        .unwrap();
    let summary = &report["summary"];
    assert_eq!(summary["reason"], "fault", "{summary}");
    let fault = summary["fault"].as_str().unwrap_or_default();
    assert!(
        fault.contains("camera keeps seeing the robot elsewhere"),
        "{summary}"
    );
    // Stopped: the robot takes no more Twists (it reports once a second).
    let twists = |said: &str| serde_json::from_str::<Value>(said).unwrap()["twists"].as_u64();
    tokio::time::sleep(Duration::from_millis(2500)).await;
    let then = twists(&said.lock().unwrap());
    tokio::time::sleep(Duration::from_millis(2500)).await;
    let now = twists(&said.lock().unwrap());
    assert_eq!(then, now, "the stuck robot is still driven");
    // It stuck at 8 cm, and odometry went no further than the lab let it.
    let last: Value = serde_json::from_str(&said.lock().unwrap()).unwrap();
    let odometry = (last["x"].as_f64().unwrap() - 0.1).hypot(last["y"].as_f64().unwrap() - 0.12);
    assert!(odometry < 0.4, "the wheels were stopped soon: {last}");
}

/// Whether `watcher` is told the robot is `state` within 8 s.
async fn robot_is(watcher: &mut Peer, state: &str) -> bool {
    let deadline = Instant::now() + Duration::from_secs(8);
    while Instant::now() < deadline {
        if let Some(status) = watcher.next_of("status", Duration::from_millis(500)).await
            && status["robot"] == state
        {
            return true;
        }
    }
    false
}

/// A stranger writing as the robot (its GID, numbers ahead of its own):
/// the odometry contradicts itself, and the lab stops driving the robot
/// (offline) until it is the robot's own again.
async fn untrusted_while_forged(python: &str, port: u16, url: &str) {
    let mut watcher = Peer::connect(url).await;
    watcher.hello("observer").await;
    let forging = {
        let python = python.to_owned();
        std::thread::spawn(move || step(&python, port, &["forge_odom", "3", "copy"]))
    };
    assert!(
        robot_is(&mut watcher, "offline").await,
        "the forged robot is still driven"
    );
    let forged = forging.join().unwrap();
    assert!(forged["sent"].as_u64().unwrap() > 300, "{forged}");
    assert!(
        robot_is(&mut watcher, "online").await,
        "the robot is not trusted again"
    );
}

/// Cells behind a gateway each publish in a namespace of their own, on
/// the gateway's Zenoh router: one ROS 2 network sees them all apart.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gateway_s_cells_are_ros_2_namespaces() {
    let Some(python) = python() else { return };
    let _alone = alone().await;
    let keys = Keys::new("ros2");
    let credentials = keys.cells(&["a", "b"]);
    let rviz = keys.issue("--ros2", "rviz");
    let (_gateway, _, zenoh) = start_gateway(&keys);
    let port: u16 = zenoh.rsplit_once(':').unwrap().1.parse().unwrap();
    let mut cells = Vec::new();
    for (name, credentials) in ["a", "b"].into_iter().zip(&credentials) {
        let args = ["--ros2"];
        cells.push(start_cell_with(&zenoh, name, credentials, &args));
    }
    // A ROS 2 machine joins the gateway's network with the credentials
    // the gateway issued it (tests/gateway.rs: strangers do not).
    let listed = step_with(
        python,
        port,
        &["list", "20", "/a/odom", "/b/odom", "/a/map", "/b/map"],
        Some(&rviz),
    );
    for cell in ["a", "b"] {
        for (topic, ty) in &TYPES[..6] {
            let named = format!("/{cell}{topic}");
            assert_eq!(
                listed["listed"][&named],
                serde_json::json!([ty]),
                "{named}: {listed}"
            );
        }
    }
    assert!(
        listed["listed"].get("/odom").is_none(),
        "no cell is at the root: {listed}"
    );
}

/// `--robot ros2` with no robot on the network says so, and stops.
#[test]
fn a_missing_ros_2_robot_is_a_clear_error() {
    let zenoh = format!("tcp/127.0.0.1:{}", free_port());
    let args = host_args(&zenoh, &["--no-record", "--robot", "ros2"]);
    let out = common::vl(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!out.status.success());
    let said = common::stderr(&out);
    assert!(
        said.contains("no ROS 2 robot: nothing on /odom within 10 s"),
        "{said}"
    );
}
