//! What a class watching costs the lab: a Host started as its own process
//! (`vl host`, simulated, camera at 15 fps), its operator teleoperating
//! under event-based control, and rounds that alternate between no one
//! watching and `watchers` clients reading everything as the web page
//! does (every feedback and frame). The Host's processor time is read
//! from `/proc` over each round, so the watchers' own work is not counted.

use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::task::JoinSet;
use vl_core::{GuestMessage, nearest_rank};
use vl_report::table::{Report, Table};

use super::{
    BenchError, Observed, Process, Socket, cpu_seconds, observe, observer, say, teleoperating,
    time_commands,
};

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

/// Starts the Host at `vl` on the open arena; it and its address.
fn start_host(vl: &Path) -> Result<(Process, String), BenchError> {
    let args = [
        "host",
        "--listen",
        "127.0.0.1:0",
        "--arena",
        "open",
        "--robot",
        "sim",
        "--camera",
        "sim",
        "--no-record",
    ];
    Process::start(vl, &args, "vl host listening on ")
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
    let pid = host.pid();
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
    let mut frames_hz: Vec<f64> = fed.iter().map(|o| o.frames as f64 / o.seconds).collect();
    frames_hz.sort_by(f64::total_cmp);
    let feedback_hz_min = fed
        .iter()
        .map(|o| o.feedback as f64 / o.seconds)
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
) -> Observed {
    use futures_util::{SinkExt, StreamExt};
    use tokio_tungstenite::tungstenite::Message;
    let began = Instant::now();
    let (mut poses, mut images, mut bytes) = (0, 0, 0);
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
                    bytes += data.len() as u64;
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
    Observed {
        feedback: poses,
        frames: images,
        bytes,
        seconds: began.elapsed().as_secs_f64(),
    }
}

/// The `p` quantile of `took`, sorted or not.
fn q(took: &[f64], p: f64) -> f64 {
    let mut sorted = took.to_vec();
    sorted.sort_by(f64::total_cmp);
    nearest_rank(&sorted, p).unwrap_or(f64::NAN)
}
