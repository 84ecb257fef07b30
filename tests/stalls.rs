//! The robot stops clear by itself when the lab machine stalls. The
//! Khepera emulator, at real line timing, is driven flat out at a wall, a
//! box and a large virtual polygon through `vl host`'s serial driver; at a
//! random moment of the approach the Host *and* its serial guard are
//! stopped (SIGSTOP: what a kernel stall, a swap storm or a debugger does)
//! and left stopped for 2.5 s. Whatever it was last told, the robot must
//! come to rest on its own, without touching anything in the emulator's
//! own truth (its `--truth` lines) and, for the virtual polygon, without
//! its body entering it. The same again with twice as many busy programs
//! as cores competing with the Host at its own priority.
//!
//! Each run prints its figures (`stall …` lines); `bench/stalls.sh` runs
//! many more and tabulates how far the robot went after the freeze against
//! the braking distance its leash budgets.

use crate::common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::json;

use common::peer::Peer;
use common::{VlProcess, big_polygon, start_khepera_host_with, vl_command};

/// The virtual polygon's centre and radius, mm, and the robot's radius.
const POLYGON: (f64, f64, f64) = (380.0, 300.0, 80.0);
const ROBOT_RADIUS_MM: f64 = 35.0;
/// How long the Host and guard stay stopped: the longest leash runs out
/// in far less.
const FROZEN: Duration = Duration::from_millis(2500);
/// How far past its leash a wheel may roll, mm: the controller's lag.
const PAST_LEASH_MM: f64 = 2.0;
/// A stopped robot's speed controller (`D,0,0`): its lag, s, and its
/// braking, mm/s² (the Khepera's speed response).
const SPEED_LAG_S: f64 = 0.03;
const SPEED_BRAKING_MM_S2: f64 = 4000.0;

/// Where the robot starts, facing what.
struct Scene {
    what: &'static str,
    arena: &'static str,
    start: &'static str,
    polygon: bool,
}

const SCENES: [Scene; 3] = [
    // 265 mm from the open arena's east wall.
    Scene {
        what: "wall",
        arena: "open",
        start: "300,300,0",
        polygon: false,
    },
    // At the first box of the navigation arena (its face at x = 250 mm).
    Scene {
        what: "box",
        arena: "navigation",
        start: "100,150,0",
        polygon: false,
    },
    // At a large virtual polygon in the middle of the open arena.
    Scene {
        what: "polygon",
        arena: "open",
        start: "150,300,0",
        polygon: true,
    },
];

/// The emulator's truth as it last said it: time, pose, contacts so far,
/// and how far the wheels may still go to their position targets (the
/// leash the Host last gave), if they have targets.
#[derive(Debug, Clone, Copy, Default)]
struct Truth {
    t_s: f64,
    x_mm: f64,
    y_mm: f64,
    contacts: u64,
    leash_mm: Option<f64>,
    /// The targets as the wheels' travel, mm, which only the Host moves.
    targets: Option<(f64, f64)>,
}

/// What a run's truth showed.
#[derive(Debug, Default)]
struct Witnessed {
    now: Truth,
    /// The deepest the body went into the virtual polygon, mm.
    into_polygon_mm: f64,
    history: Vec<Truth>,
}

/// `vl khepera-emu --truth`, its truth lines read as they come.
struct Emulator {
    _process: VlProcess,
    device: String,
    told: Arc<Mutex<Witnessed>>,
}

impl Emulator {
    fn start(baud: u32, scene: &Scene) -> Emulator {
        let baud = baud.to_string();
        let mut child = vl_command()
            .args([
                "khepera-emu",
                "--truth",
                "--baud",
                &baud,
                "--arena",
                scene.arena,
                "--start",
                scene.start,
            ])
            .stdout(Stdio::piped())
            .spawn()
            .expect("vl khepera-emu starts");
        let mut lines = BufReader::new(child.stdout.take().expect("piped")).lines();
        let first = lines.next().expect("a first line").expect("text");
        let device = first.rsplit(' ').next().expect("a device").to_owned();
        let told = Arc::new(Mutex::new(Witnessed::default()));
        let polygon = scene.polygon;
        let shared = told.clone();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                let fields: Vec<&str> = line.split_whitespace().collect();
                let mut told = shared.lock().unwrap();
                // A leash line tells of the truth line before it.
                if let ["leash", _, rest @ ..] = &fields[..] {
                    let told = &mut *told;
                    if let Some(last) = told.history.last_mut() {
                        let number = |i: usize| rest.get(i).and_then(|v| v.parse::<f64>().ok());
                        last.leash_mm = number(0);
                        last.targets = number(1).zip(number(2));
                        told.now = *last;
                    }
                    continue;
                }
                let ["truth", t, x, y, _, contacts] = fields[..] else {
                    continue;
                };
                let truth = Truth {
                    t_s: t.parse().unwrap_or(0.0),
                    x_mm: x.parse().unwrap_or(0.0),
                    y_mm: y.parse().unwrap_or(0.0),
                    contacts: contacts.parse().unwrap_or(u64::MAX),
                    leash_mm: None,
                    targets: None,
                };
                if polygon {
                    let (px, py, r) = POLYGON;
                    // The 256-gon's edges lie within r·(1 − cos(π/256)) of the circle.
                    let depth = r + ROBOT_RADIUS_MM - (truth.x_mm - px).hypot(truth.y_mm - py);
                    told.into_polygon_mm = told.into_polygon_mm.max(depth);
                }
                told.now = truth;
                told.history.push(truth);
            }
        });
        Emulator {
            _process: VlProcess(child),
            device,
            told,
        }
    }

    fn truth(&self) -> Truth {
        self.told.lock().unwrap().now
    }
}

/// Sends `signal` to process `pid`.
fn signal(pid: u32, signal: libc::c_int) {
    // SAFETY: kill only reads its integer arguments.
    let sent = unsafe { libc::kill(pid as libc::pid_t, signal) };
    assert_eq!(sent, 0, "signal {signal} to {pid}");
}

/// The processes `pid` started (the Host's serial guard), from /proc.
fn children(pid: u32) -> Vec<u32> {
    let mut found = Vec::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return found;
    };
    for task in tasks.flatten() {
        let listed = std::fs::read_to_string(task.path().join("children")).unwrap_or_default();
        found.extend(
            listed
                .split_whitespace()
                .filter_map(|c| c.parse::<u32>().ok()),
        );
    }
    found
}

/// Busy programs at the caller's priority, killed when dropped.
struct Busy(Vec<Child>);

impl Busy {
    fn start(count: usize) -> Busy {
        Busy(
            (0..count)
                .map(|_| {
                    Command::new("sh")
                        .args(["-c", "while :; do :; done"])
                        .spawn()
                        .expect("sh starts")
                })
                .collect(),
        )
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A small deterministic generator for the freeze moments (xorshift).
struct Moments(u64);

impl Moments {
    /// A moment from 0.05 to 0.9 s.
    fn next(&mut self) -> Duration {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        Duration::from_secs_f64(0.05 + 0.85 * (self.0 % 10_000) as f64 / 10_000.0)
    }
}

/// What one stalled run showed.
#[derive(Debug)]
struct Stall {
    contacts: u64,
    into_polygon_mm: f64,
    /// From the Host's last extension of the leash: the robot's speed, mm/s,
    /// how far it went after, mm, and how far the leash let it go (none:
    /// the wheels were stopped).
    speed_mm_s: f64,
    after_mm: f64,
    leash_mm: Option<f64>,
    /// Whether it was at rest when the Host woke.
    at_rest: bool,
}

async fn stalled_run(baud: u32, scene: &Scene, freeze_after: Duration) -> Stall {
    let emulator = Emulator::start(baud, scene);
    let baud_text = baud.to_string();
    let flags = [
        "--camera",
        "none",
        "--experiments",
        "navigation",
        "--no-reset",
        "--baud",
        &baud_text,
        "--arena",
        scene.arena,
        "--start",
        scene.start,
    ];
    let (host, url) = start_khepera_host_with(&emulator.device, &flags);
    let mut op = Peer::connect(&url).await;
    op.hello("operator").await;
    op.send(json!({"type": "mount", "experiment": "navigation"}))
        .await;
    op.expect("mounted").await;
    let virtual_obstacles = if scene.polygon {
        big_polygon(POLYGON.0, POLYGON.1, POLYGON.2)
    } else {
        json!([])
    };
    op.send(json!({"type": "define", "virtual_obstacles": virtual_obstacles}))
        .await;
    op.expect("defined").await;
    op.send(json!({"type": "start"})).await;
    op.expect("started").await;
    // Flat out, one command after each feedback, until the freeze.
    let began = Instant::now();
    let mut event = 1u64;
    while began.elapsed() < freeze_after {
        op.send(json!({"type": "command", "event": event, "left": 1000.0, "right": 1000.0}))
            .await;
        loop {
            let f = op.expect("feedback").await;
            if f["event"].as_u64() >= Some(event) {
                break;
            }
        }
        event += 1;
    }
    let guards = children(host.0.id());
    assert!(!guards.is_empty(), "the Host runs a serial guard");
    signal(host.0.id(), libc::SIGSTOP);
    for &guard in &guards {
        signal(guard, libc::SIGSTOP);
    }
    tokio::time::sleep(FROZEN).await;
    let woke = emulator.truth();
    let told = emulator.told.lock().unwrap();
    // The Host's last extension of the leash, on the robot's own clock:
    // the first line with the targets the robot was left with. From there
    // the robot may go no further than that leash.
    let history = &told.history;
    let extended = (1..history.len())
        .rev()
        .find(|&i| history[i - 1].targets != history[i].targets)
        .unwrap_or(0);
    let last = history.get(extended).copied().unwrap_or(woke);
    let before = history
        .get(extended.saturating_sub(1))
        .copied()
        .unwrap_or(last);
    let dt = (last.t_s - before.t_s).max(1e-3);
    let speed_mm_s = (last.x_mm - before.x_mm).hypot(last.y_mm - before.y_mm) / dt;
    let last_half_second: Vec<&Truth> =
        history.iter().filter(|t| t.t_s >= woke.t_s - 0.5).collect();
    let at_rest = last_half_second
        .windows(2)
        .all(|w| (w[1].x_mm - w[0].x_mm).hypot(w[1].y_mm - w[0].y_mm) < 0.2);
    let stall = Stall {
        contacts: woke.contacts,
        into_polygon_mm: told.into_polygon_mm,
        speed_mm_s,
        after_mm: (woke.x_mm - last.x_mm).hypot(woke.y_mm - last.y_mm),
        leash_mm: last.leash_mm,
        at_rest,
    };
    drop(told);
    for &guard in &guards {
        signal(guard, libc::SIGCONT);
    }
    signal(host.0.id(), libc::SIGCONT);
    stall
}

/// Every baud and scene, frozen at random moments: `runs` each.
async fn stall_everywhere(busy: usize, runs: usize, seed: u64) {
    let _busy = Busy::start(busy);
    let mut moments = Moments(seed);
    let mut failures = Vec::new();
    let mut count = 0;
    for baud in [9600, 38400, 115200] {
        for scene in &SCENES {
            for _ in 0..runs {
                let at = moments.next();
                let s = stalled_run(baud, scene, at).await;
                count += 1;
                // Left stopped, the wheels brake as the speed controller does.
                let leash = s.leash_mm.unwrap_or(
                    s.speed_mm_s * SPEED_LAG_S + s.speed_mm_s.powi(2) / (2.0 * SPEED_BRAKING_MM_S2),
                );
                println!(
                    "stall baud={baud} scene={} busy={busy} freeze_s={:.3} speed_mm_s={:.0} after_mm={:.1} leash_mm={leash:.1} contacts={} into_polygon_mm={:.1} at_rest={}",
                    scene.what,
                    at.as_secs_f64(),
                    s.speed_mm_s,
                    s.after_mm,
                    s.contacts,
                    s.into_polygon_mm,
                    s.at_rest
                );
                // A wheel goes no further than its leash; the body's centre,
                // between two wheels, no further than the longer one.
                let within = s.after_mm <= leash + PAST_LEASH_MM;
                if s.contacts > 0 || s.into_polygon_mm > 0.0 || !s.at_rest || !within {
                    failures.push(format!(
                        "{baud} baud, {} frozen after {at:?}: {s:?}",
                        scene.what
                    ));
                }
            }
        }
    }
    assert_eq!(count, 9 * runs, "every baud and scene");
    assert!(failures.is_empty(), "seed {seed}: {failures:#?}");
}

/// Runs per baud and scene: STALL_RUNS (the bench sets more), else 4:
/// 36 stalls a machine.
fn runs() -> usize {
    std::env::var("STALL_RUNS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(4)
}

/// The freeze moments' seed: STALL_SEED, else the clock (printed).
fn seed() -> u64 {
    let seed = std::env::var("STALL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| d.as_nanos() as u64)
        })
        | 1;
    println!("stall seed {seed}");
    seed
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frozen_host_leaves_a_robot_that_stops_clear_by_itself() {
    let _alone = crate::alone().await;
    stall_everywhere(0, runs(), seed()).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frozen_host_on_a_starved_machine_leaves_a_robot_that_stops_clear() {
    let _alone = crate::alone().await;
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    stall_everywhere(2 * cores, runs(), seed()).await;
}
