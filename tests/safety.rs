//! The safety layer from outside: `vl host` processes on the simulated lab,
//! driven over their sockets the way a careless operator would — the stick
//! at full deflection in random directions, from random starting places,
//! in every shipped arena — must never let the robot touch anything, and
//! must keep the run going until it is stopped.

use crate::common;

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::connect_async;
use tokio_tungstenite::tungstenite::Message;
use vl_core::{Arena, Joystick, Point, RobotModel, Teleop};

use common::{VlProcess, start_host};

/// A small deterministic generator, so a failing seed can be rerun.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// How a run asks the robot to move.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Driving {
    /// Teleoperation, the stick at full deflection in a new random
    /// direction every second.
    Stick,
    /// Navigation, full speed straight ahead: a follower whose path leads
    /// into a wall.
    StraightAhead,
}

/// What one run showed.
#[derive(Debug)]
struct Outcome {
    label: String,
    contacts: u64,
    /// The least room between the body and anything, by the exact
    /// geometry of the arena at the reported (true, simulated) pose, mm.
    closest_mm: f64,
    /// Mean forward speed over the forward speed asked, as the Host saw it.
    speed_kept: f64,
    events: u64,
    limited_events: u64,
}

/// A random place where the robot stands clear of everything.
fn free_start(arena: &Arena, robot: &RobotModel, rng: &mut Rng) -> (f64, f64, f64) {
    loop {
        let p = Point {
            x_mm: rng.next() * arena.width_mm,
            y_mm: rng.next() * arena.height_mm,
        };
        if arena.is_free(p, robot.radius_mm + 5.0) {
            return (p.x_mm, p.y_mm, (rng.next() - 0.5) * std::f64::consts::TAU);
        }
    }
}

/// A Host on `arena` with the robot at a random free place (and `model`,
/// when given, from that file).
fn host(arena: &str, seed: u64, model: Option<&str>) -> (VlProcess, String, Arena, RobotModel) {
    let map = Arena::load(arena).unwrap();
    let robot = match model {
        Some(file) => RobotModel::from_json(&std::fs::read_to_string(file).unwrap()).unwrap(),
        None => RobotModel::khepera_ii(),
    };
    let (x, y, theta) = free_start(&map, &robot, &mut Rng(seed * 7919 + 17));
    let start = format!("{x:.1},{y:.1},{theta:.3}");
    let seed_text = seed.to_string();
    let mut args = vec![
        "--camera", "none", "--arena", arena, "--start", &start, "--seed", &seed_text,
    ];
    if let Some(file) = model {
        args.extend(["--robot-model", file]);
    }
    let (process, url) = start_host(&args);
    (process, url, map, robot)
}

/// The next text message of `kind`, skipping others; panics after 5 s.
async fn expect<S>(ws: &mut S, kind: &str) -> Value
where
    S: StreamExt<Item = Result<Message, tokio_tungstenite::tungstenite::Error>> + Unpin,
{
    tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match ws.next().await {
                Some(Ok(Message::Text(t))) => {
                    let v: Value = serde_json::from_str(&t).unwrap();
                    if v["type"] == kind {
                        return v;
                    }
                    assert_ne!(v["type"], "done", "the run ended by itself: {v}");
                    assert_ne!(v["type"], "error", "refused: {v}");
                }
                Some(Ok(_)) => {}
                other => panic!("connection ended waiting for {kind}: {other:?}"),
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("no {kind} within 5 s"))
}

/// Drives one run for `seconds` of the Host's clock, then stops it.
async fn drive(
    url: String,
    label: String,
    arena: Arena,
    robot: RobotModel,
    driving: Driving,
    seconds: f64,
    seed: u64,
) -> Outcome {
    let (ws, _) = connect_async(&url).await.expect("connects");
    let (mut tx, mut rx) = ws.split();
    let send = |v: Value| Message::text(v.to_string());
    tx.send(send(
        json!({"type": "hello", "protocol": 1, "role": "operator"}),
    ))
    .await
    .unwrap();
    expect(&mut rx, "welcome").await;
    let experiment = match driving {
        Driving::Stick => "teleoperation",
        Driving::StraightAhead => "navigation",
    };
    tx.send(send(json!({"type": "mount", "experiment": experiment})))
        .await
        .unwrap();
    expect(&mut rx, "mounted").await;
    // No path: the commands drive, guarded live, and there is nothing
    // for the lab's twin to try first.
    tx.send(send(json!({"type": "define"}))).await.unwrap();
    expect(&mut rx, "defined").await;
    tx.send(send(json!({"type": "start"}))).await.unwrap();
    expect(&mut rx, "started").await;

    let teleop = Teleop::default();
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9) | 1);
    let (mut stick, mut changed_at) = (Joystick::default(), f64::NEG_INFINITY);
    let mut outcome = Outcome {
        label,
        contacts: 0,
        closest_mm: f64::INFINITY,
        speed_kept: 0.0,
        events: 0,
        limited_events: 0,
    };
    let mut started_ms = None;
    let mut event = 0u64;
    loop {
        let f = expect(&mut rx, "feedback").await;
        let t = f["t_ms"].as_f64().unwrap();
        let t0 = *started_ms.get_or_insert(t);
        let p = Point {
            x_mm: f["pose"]["x_mm"].as_f64().unwrap(),
            y_mm: f["pose"]["y_mm"].as_f64().unwrap(),
        };
        outcome.closest_mm = outcome.closest_mm.min(arena.clearance(p) - robot.radius_mm);
        if f["contact"] == true {
            outcome.contacts += 1;
        }
        if f["limited"] == true {
            outcome.limited_events += 1;
        }
        if t - t0 >= seconds * 1e3 {
            break;
        }
        if f["event"].as_u64() != Some(event) {
            continue; // Event-based: wait for the feedback of the last command.
        }
        if t - changed_at >= 1000.0 {
            let a = rng.next() * std::f64::consts::TAU;
            stick = Joystick {
                x: a.cos(),
                y: a.sin(),
            };
            changed_at = t;
        }
        let wheels = match driving {
            Driving::Stick => teleop.wheels(&robot, teleop.desired(stick)),
            Driving::StraightAhead => robot.wheels_for(robot.max_wheel_speed_mm_s, 0.0),
        };
        event += 1;
        let command = json!({"type": "command", "event": event,
            "left": wheels.left_mm_s, "right": wheels.right_mm_s});
        tx.send(send(command)).await.unwrap();
    }
    tx.send(send(json!({"type": "stop"}))).await.unwrap();
    let done = expect(&mut rx, "done").await;
    let summary = &done["summary"];
    assert_eq!(summary["reason"], "stopped", "{done}");
    assert_eq!(summary["collisions"], 0, "{}: {done}", outcome.label);
    outcome.events = event;
    outcome.speed_kept = summary["speed_kept"].as_f64().unwrap_or(1.0);
    outcome
}

/// Runs every `(arena, seed)` at once, each on its own Host.
async fn batch(
    runs: &[(&str, u64)],
    driving: Driving,
    model: Option<&str>,
    seconds: f64,
) -> Vec<Outcome> {
    let mut hosts = Vec::new();
    let mut tasks = Vec::new();
    for &(arena, seed) in runs {
        let (process, url, map, robot) = host(arena, seed, model);
        hosts.push(process);
        let label = format!("{arena} seed {seed} ({driving:?})");
        tasks.push(tokio::spawn(drive(
            url, label, map, robot, driving, seconds, seed,
        )));
    }
    let mut outcomes = Vec::new();
    for task in tasks {
        outcomes.push(task.await.expect("the run's task"));
    }
    drop(hosts);
    outcomes
}

fn report(outcomes: &[Outcome]) {
    let runs = outcomes.len();
    let contacts: u64 = outcomes.iter().map(|o| o.contacts).sum();
    let closest = outcomes
        .iter()
        .map(|o| o.closest_mm)
        .fold(f64::INFINITY, f64::min);
    let kept = outcomes.iter().map(|o| o.speed_kept).sum::<f64>() / runs as f64;
    let events: u64 = outcomes.iter().map(|o| o.events).sum();
    let limited: u64 = outcomes.iter().map(|o| o.limited_events).sum();
    println!(
        "{runs} runs, {events} commands: {contacts} contacts, closest approach {closest:.1} mm, \
         speed kept {:.1} % on average, the layer held back {limited} feedbacks",
        kept * 100.0
    );
    for o in outcomes {
        assert_eq!(o.contacts, 0, "{o:?}");
        assert!(o.closest_mm > 0.0, "{o:?}");
    }
}

/// 20 seeds × every shipped arena × 20 s of random full-deflection stick.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn random_full_stick_never_touches_anything() {
    let mut all = Vec::new();
    for arena in Arena::shipped() {
        let runs: Vec<(&str, u64)> = (1..=20).map(|seed| (arena, seed)).collect();
        all.extend(batch(&runs, Driving::Stick, None, 20.0).await);
    }
    report(&all);
}

/// A faster robot, and the navigation experiment's commands driven
/// straight at whatever is ahead.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_faster_robot_and_a_follower_into_a_wall_stop_short() {
    let dir = common::scratch("safety-fast");
    let fast = RobotModel {
        name: "fast khepera".into(),
        max_wheel_speed_mm_s: 2000.0,
        ..RobotModel::khepera_ii()
    };
    let file = dir.join("fast.json");
    std::fs::write(&file, serde_json::to_string(&fast).unwrap()).unwrap();
    let runs: Vec<(&str, u64)> = Arena::shipped()
        .flat_map(|a| [(a, 101), (a, 102)])
        .collect();
    let mut all = batch(&runs, Driving::Stick, Some(common::s(&file)), 10.0).await;
    all.extend(batch(&runs, Driving::StraightAhead, Some(common::s(&file)), 10.0).await);
    all.extend(batch(&runs, Driving::StraightAhead, None, 10.0).await);
    report(&all);
}

/// Pushed straight at a wall with no turn asked, the robot is not turned:
/// neither the safety layer nor the assistance's potential fields (whose
/// sideways part, where they hold the robot still, would spin it in place)
/// turn a robot nobody asked to turn. With and without a camera.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stick_pushed_straight_at_a_wall_never_turns_the_robot() {
    for camera in ["sim", "none"] {
        let (_host, url) = start_host(&["--camera", camera, "--no-reset"]);
        let mut op = common::peer::Peer::connect(&url).await;
        op.hello("operator").await;
        op.start("teleoperation").await;
        let began = std::time::Instant::now();
        let (mut turned, mut last) = (0.0f64, Value::Null);
        let mut event = 1u64;
        // 150 mm/s straight ahead, into the navigation arena's first box,
        // and on pushing for seconds after the robot stopped.
        while began.elapsed() < Duration::from_secs(5) {
            last = op.command(event, json!({"v": 150.0, "w": 0.0})).await;
            turned = turned.max(last["pose"]["theta_rad"].as_f64().unwrap().abs());
            event += 1;
        }
        let x = last["pose"]["x_mm"].as_f64().unwrap();
        assert!(
            x > 200.0,
            "camera {camera}: the robot reached the box: {last}"
        );
        assert!(
            turned < 0.05,
            "camera {camera}: turned by {turned:.3} rad with no turn asked: {last}"
        );
    }
}
