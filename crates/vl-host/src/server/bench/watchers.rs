//! What a class watching costs the lab: a Host started as its own process
//! (`vl host`, simulated, camera at 15 fps), its operator teleoperating
//! under event-based control, and rounds that alternate between no one
//! watching and `watchers` clients reading everything as the web page
//! does (every feedback and frame). The Host's processor time is read
//! from `/proc` over each round, so the watchers' own work is not counted.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::task::JoinSet;
use vl_core::{GuestMessage, nearest_rank};
use vl_report::table::{Report, Table};

use super::{BenchError, Socket, observe, observer, say, teleoperating, time_commands};

/// `vl host bench-watchers`: a Host of its own (this `vl`, simulated,
/// camera at 15 fps) and its operator's command → feedback with no one
/// watching against `--watchers` clients reading everything as the web
/// page does, in alternating rounds; the Host's processor time; the
/// frames each watcher got.
#[derive(Debug, Clone)]
pub struct WatchersBench {
    /// Clients watching in the watched rounds (at most 240, what a Host
    /// accepts beside its operator).
    pub watchers: u64,
    /// Commands timed in each round.
    pub commands: u64,
    /// Rounds of each kind, alternating.
    pub rounds: u64,
    /// The watchers are Foxglove clients subscribed to every channel,
    /// rather than web pages.
    pub foxglove: bool,
}

impl WatchersBench {
    /// Runs the bench on a Host started from the binary at `vl`.
    pub async fn run(&self, vl: &Path) -> Result<WatchersCost, BenchError> {
        let size = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
        watchers_cost(
            vl,
            size(self.watchers),
            size(self.commands),
            size(self.rounds),
            self.foxglove,
        )
        .await
    }
}

/// The watchers' cost against none, in one run.
#[derive(Debug, Clone, Serialize)]
pub struct WatchersCost {
    pub watchers: usize,
    /// Foxglove clients, subscribed to every channel (else web pages).
    pub foxglove: bool,
    /// Commands timed in each round, and rounds of each kind.
    pub commands: usize,
    pub rounds: usize,
    pub idle_p50_ms: f64,
    pub idle_p99_ms: f64,
    pub watched_p50_ms: f64,
    pub watched_p99_ms: f64,
    /// Watched p99 over idle p99.
    pub p99_ratio: f64,
    /// The Host process's processor time over wall time (1.0: one core
    /// busy), in the idle and the watched rounds.
    pub host_cores_idle: f64,
    pub host_cores_watched: f64,
    /// Frames a second to the slowest watcher, and to the median one.
    pub frames_hz_min: f64,
    pub frames_hz_median: f64,
    /// Feedback a second to the slowest watcher.
    pub feedback_hz_min: f64,
}

impl Report for WatchersCost {
    fn table(&self) -> Table {
        Table::pairs([
            (
                "watchers",
                format!(
                    "{} {}",
                    self.watchers,
                    if self.foxglove {
                        "Foxglove clients, subscribed to every channel"
                    } else {
                        "web pages"
                    }
                ),
            ),
            (
                "commands timed",
                format!("{} a round, {} rounds of each", self.commands, self.rounds),
            ),
            (
                "command → feedback, no one watching",
                format!(
                    "p50 {:.2} ms, p99 {:.2} ms",
                    self.idle_p50_ms, self.idle_p99_ms
                ),
            ),
            (
                "command → feedback, watched",
                format!(
                    "p50 {:.2} ms, p99 {:.2} ms ({:.2}× idle)",
                    self.watched_p50_ms, self.watched_p99_ms, self.p99_ratio
                ),
            ),
            (
                "the Host's processor",
                format!(
                    "{:.2} cores idle, {:.2} cores watched",
                    self.host_cores_idle, self.host_cores_watched
                ),
            ),
            (
                "frames to each watcher",
                format!(
                    "{:.1} /s the slowest, {:.1} /s the median",
                    self.frames_hz_min, self.frames_hz_median
                ),
            ),
            (
                "feedback to the slowest watcher",
                format!("{:.1} /s", self.feedback_hz_min),
            ),
        ])
    }
}

/// `vl host` as a child process, killed when dropped.
struct HostProcess(Child);

impl Drop for HostProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts the Host at `vl` on the open arena; it and its address.
fn start_host(vl: &Path) -> Result<(HostProcess, String), BenchError> {
    let child = Command::new(vl)
        .args(["host", "--listen", "127.0.0.1:0", "--arena", "open"])
        .args(["--robot", "sim", "--camera", "sim", "--no-record"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| BenchError::Connect(format!("cannot start {}: {e}", vl.display())))?;
    let mut host = HostProcess(child);
    let stdout = host.0.stdout.take().expect("piped stdout");
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .map_err(|e| BenchError::Connect(e.to_string()))?;
    let url = line
        .trim()
        .strip_prefix("vl host listening on ")
        .ok_or_else(|| BenchError::Connect(format!("the Host said {line:?}")))?
        .to_owned();
    Ok((host, url))
}

/// The processor time `pid` has used so far, s (user and system).
fn cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return f64::NAN;
    };
    // The fields after the command's name, which may hold spaces.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or(vec![], |(_, rest)| rest.split_whitespace().collect());
    let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok());
    // utime and stime are the stat's 14th and 15th fields.
    match (ticks(11), ticks(12)) {
        (Some(user), Some(system)) => (user + system) / clock_ticks(),
        _ => f64::NAN,
    }
}

fn clock_ticks() -> f64 {
    #[cfg(target_os = "linux")]
    // SAFETY: sysconf reads a constant of the system.
    let ticks = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    #[cfg(not(target_os = "linux"))]
    let ticks = 100.0;
    ticks
}

/// Times `commands` from `event` on; the times, and the Host's cores busy.
async fn round(
    operator: &mut Socket,
    event: &mut u64,
    commands: usize,
    pid: u32,
) -> Result<(Vec<f64>, f64), BenchError> {
    let (cpu, wall) = (cpu_seconds(pid), Instant::now());
    let took = time_commands(operator, *event, commands, || false).await?;
    *event += took.len() as u64;
    let cores = (cpu_seconds(pid) - cpu) / wall.elapsed().as_secs_f64();
    Ok((took, cores))
}

/// Runs the bench on the Host at `vl`, saying each round's figures on
/// standard error as it goes.
async fn watchers_cost(
    vl: &Path,
    watchers: usize,
    commands: usize,
    rounds: usize,
    foxglove: bool,
) -> Result<WatchersCost, BenchError> {
    let (host, url) = start_host(vl)?;
    let pid = host.0.id();
    let mut operator = teleoperating(&url, None).await?;
    let mut event = 1;
    let (mut idle, mut watched) = (Vec::new(), Vec::new());
    let (mut idle_cores, mut watched_cores) = (Vec::new(), Vec::new());
    let mut fed = Vec::new();
    for r in 1..=rounds {
        let (took, cores) = round(&mut operator, &mut event, commands, pid).await?;
        eprintln!(
            "round {r}/{rounds}, no one watching: p99 {:.2} ms, Host {cores:.2} cores",
            q(&took, 0.99)
        );
        idle.extend(took);
        idle_cores.push(cores);
        let (stop_tx, stop) = tokio::sync::watch::channel(false);
        let mut reading = JoinSet::new();
        for _ in 0..watchers {
            if foxglove {
                let ws = foxglove_client(&url).await?;
                reading.spawn(watch_in_foxglove(ws, stop.clone()));
            } else {
                let ws = observer(&url).await?;
                reading.spawn(observe(ws, stop.clone()));
            }
        }
        // The class is in, the first frames sent: now time.
        tokio::time::sleep(Duration::from_secs(1)).await;
        let (took, cores) = round(&mut operator, &mut event, commands, pid).await?;
        let _ = stop_tx.send(true);
        while let Some(read) = reading.join_next().await {
            fed.push(read.unwrap_or_default());
        }
        eprintln!(
            "round {r}/{rounds}, {watchers} watching: p99 {:.2} ms, Host {cores:.2} cores",
            q(&took, 0.99)
        );
        watched.extend(took);
        watched_cores.push(cores);
    }
    let _ = say(&mut operator, &GuestMessage::Bye).await;
    drop(host);
    let mut frames_hz: Vec<f64> = fed.iter().map(|(_, f, s)| *f as f64 / s).collect();
    frames_hz.sort_by(f64::total_cmp);
    let feedback_hz_min = fed
        .iter()
        .map(|(f, _, s)| *f as f64 / s)
        .fold(f64::INFINITY, f64::min);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Ok(WatchersCost {
        watchers,
        foxglove,
        commands,
        rounds,
        idle_p50_ms: q(&idle, 0.5),
        idle_p99_ms: q(&idle, 0.99),
        watched_p50_ms: q(&watched, 0.5),
        watched_p99_ms: q(&watched, 0.99),
        p99_ratio: q(&watched, 0.99) / q(&idle, 0.99),
        host_cores_idle: mean(&idle_cores),
        host_cores_watched: mean(&watched_cores),
        frames_hz_min: frames_hz.first().copied().unwrap_or(0.0),
        frames_hz_median: frames_hz.get(frames_hz.len() / 2).copied().unwrap_or(0.0),
        feedback_hz_min: if fed.is_empty() { 0.0 } else { feedback_hz_min },
    })
}

/// A Foxglove client of the Host at `url`.
async fn foxglove_client(url: &str) -> Result<Socket, BenchError> {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let mut request = url
        .into_client_request()
        .map_err(|e| BenchError::Connect(e.to_string()))?;
    request.headers_mut().insert(
        "sec-websocket-protocol",
        tokio_tungstenite::tungstenite::http::HeaderValue::from_static("foxglove.websocket.v1"),
    );
    tokio_tungstenite::connect_async(request)
        .await
        .map(|(ws, _)| ws)
        .map_err(|e| BenchError::Connect(e.to_string()))
}

/// Subscribes to every channel advertised and reads until `stop`: the
/// poses (one a feedback) and the camera's images it got, and for how long.
async fn watch_in_foxglove(
    mut ws: Socket,
    mut stop: tokio::sync::watch::Receiver<bool>,
) -> (u64, u64, f64) {
    use futures_util::{SinkExt, StreamExt};
    use tokio_tungstenite::tungstenite::Message;
    let began = Instant::now();
    let (mut poses, mut images) = (0, 0);
    let (mut pose, mut camera) = (None, None);
    loop {
        tokio::select! {
            _ = stop.changed() => break,
            next = ws.next() => match next {
                Some(Ok(Message::Text(text))) => {
                    let op: serde_json::Value = serde_json::from_str(text.as_str()).unwrap_or_default();
                    if op["op"] != "advertise" {
                        continue;
                    }
                    let channels = op["channels"].as_array().cloned().unwrap_or_default();
                    let subscriptions: Vec<serde_json::Value> = channels
                        .iter()
                        .map(|c| serde_json::json!({"id": c["id"], "channelId": c["id"]}))
                        .collect();
                    let id_of = |topic: &str| channels.iter().find(|c| c["topic"] == topic).and_then(|c| c["id"].as_u64());
                    (pose, camera) = (id_of("/robot/pose"), id_of("/camera"));
                    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": subscriptions});
                    let _ = ws.send(Message::text(subscribe.to_string())).await;
                }
                Some(Ok(Message::Binary(data))) if data.first() == Some(&1) && data.len() >= 5 => {
                    let id = Some(u64::from(u32::from_le_bytes([data[1], data[2], data[3], data[4]])));
                    poses += u64::from(id == pose);
                    images += u64::from(id == camera);
                }
                Some(Ok(_)) => {}
                _ => break,
            },
        }
    }
    let _ = ws.close(None).await;
    (poses, images, began.elapsed().as_secs_f64())
}

/// The `p` quantile of `took`, sorted or not.
fn q(took: &[f64], p: f64) -> f64 {
    let mut sorted = took.to_vec();
    sorted.sort_by(f64::total_cmp);
    nearest_rank(&sorted, p).unwrap_or(f64::NAN)
}
