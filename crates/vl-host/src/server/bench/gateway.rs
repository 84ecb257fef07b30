//! What a gateway adds and what it saves: a gateway and `cells` simulated
//! cells as processes of their own (`vl gateway`, `vl host --gateway`), an
//! operator on every cell under event-based control, straight to the
//! cell's own port and then through the gateway, and `watchers` Guests
//! reading everything through the gateway, spread over the cells. Each
//! process's processor time is read from `/proc` over each round, the
//! gateway's bytes out as its watchers read them.

use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::task::JoinSet;
use vl_core::{GuestMessage, nearest_rank};
use vl_report::table::{Report, Table};

use super::{
    BenchError, Process, Socket, cpu_seconds, observe, observer, say, teleoperating, time_commands,
};

/// `vl gateway bench`.
#[derive(Debug, Clone)]
pub struct GatewayBench {
    pub cells: usize,
    /// Guests watching through the gateway in the watched round.
    pub watchers: usize,
    /// Commands each operator times in each round.
    pub commands: usize,
}

/// One round: the operators' command → feedback, and what each process
/// used meanwhile.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    pub p50_ms: f64,
    pub p99_ms: f64,
    /// The cells' processors together, and the busiest cell's (cores).
    pub cells_cores: f64,
    pub busiest_cell_cores: f64,
    pub gateway_cores: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct GatewayCost {
    pub cells: usize,
    pub watchers: usize,
    pub commands: usize,
    /// Each operator straight to its cell's own port.
    pub direct: Round,
    /// Through the gateway, no one watching.
    pub through: Round,
    /// Through the gateway, with the watchers.
    pub watched: Round,
    /// What the gateway adds to the operators' p99, ms (no one watching).
    pub added_p99_ms: f64,
    /// Frames a second to the slowest watcher, and to the median one.
    pub frames_hz_min: f64,
    pub frames_hz_median: f64,
    /// What the gateway sent its watchers, MB a second in all.
    pub to_watchers_mb_s: f64,
}

impl GatewayBench {
    /// Runs the bench on processes of the binary at `vl`, saying each
    /// round's figures on standard error as it goes.
    pub async fn run(&self, vl: &Path) -> Result<GatewayCost, BenchError> {
        let keys = issue_cells(vl, self.cells)?;
        let keys_arg = keys.display().to_string();
        let zenoh = format!("quic/127.0.0.1:{}", free_udp_port()?);
        let gateway_args = [
            "gateway",
            "--listen",
            "127.0.0.1:0",
            "--zenoh-listen",
            &zenoh,
            "--keys",
            &keys_arg,
        ];
        let (gateway, gateway_url) = Process::start(vl, &gateway_args, "vl gateway listening on ")?;
        let mut cells = Vec::new();
        for n in 0..self.cells {
            let name = format!("c{n}");
            let credentials = keys.join(format!("{name}.toml")).display().to_string();
            let args = [
                "host",
                "--listen",
                "127.0.0.1:0",
                "--arena",
                "open",
                "--no-record",
                "--gateway",
                &zenoh,
                "--cell",
                &name,
                "--zenoh-credentials",
                &credentials,
            ];
            cells.push(Process::start(vl, &args, "vl host listening on ")?);
        }
        until_status(&gateway_url, |s| {
            s["cells"].as_array().is_some_and(|c| c.len() == self.cells)
        })
        .await?;
        eprintln!("{} cells at the gateway", self.cells);
        let pids = Pids {
            cells: cells.iter().map(|(p, _)| p.pid()).collect(),
            gateway: gateway.pid(),
        };

        let direct_urls: Vec<String> = cells.iter().map(|(_, url)| url.clone()).collect();
        let mut operators = operators(&direct_urls).await?;
        let (direct, ops) = round(operators, self.commands, &pids).await?;
        say_bye(ops).await;
        eprintln!("straight to the cells: p99 {:.2} ms", direct.p99_ms);
        until_status(&gateway_url, |s| {
            s["cells"]
                .as_array()
                .is_some_and(|c| c.iter().all(|c| c["operator"].is_null()))
        })
        .await?;

        let through_urls = vec![gateway_url.clone(); self.cells];
        operators = operators_one_by_one(&through_urls).await?;
        let (through, ops) = round(operators, self.commands, &pids).await?;
        eprintln!("through the gateway: p99 {:.2} ms", through.p99_ms);

        let (stop_tx, stop) = tokio::sync::watch::channel(false);
        let mut reading = JoinSet::new();
        for w in 0..self.watchers {
            let ws = observer(&format!("{gateway_url}/cells/c{}", w % self.cells)).await?;
            reading.spawn(observe(ws, stop.clone()));
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
        let (watched, ops) = round(ops, self.commands, &pids).await?;
        eprintln!(
            "through the gateway, {} watching: p99 {:.2} ms",
            self.watchers, watched.p99_ms
        );
        let _ = stop_tx.send(true);
        let (mut frames_hz, mut mb_s) = (Vec::new(), 0.0);
        while let Some(read) = reading.join_next().await {
            let read = read.unwrap_or_default();
            frames_hz.push(read.frames as f64 / read.seconds.max(1e-9));
            mb_s += read.bytes as f64 / 1e6 / read.seconds.max(1e-9);
        }
        frames_hz.sort_by(f64::total_cmp);
        say_bye(ops).await;
        let _ = std::fs::remove_dir_all(&keys);
        Ok(GatewayCost {
            cells: self.cells,
            watchers: self.watchers,
            commands: self.commands,
            added_p99_ms: through.p99_ms - direct.p99_ms,
            direct,
            through,
            watched,
            frames_hz_min: frames_hz.first().copied().unwrap_or(0.0),
            frames_hz_median: frames_hz.get(frames_hz.len() / 2).copied().unwrap_or(0.0),
            to_watchers_mb_s: mb_s,
        })
    }
}

struct Pids {
    cells: Vec<u32>,
    gateway: u32,
}

/// The gateway's network as a lab runs it: a folder with the gateway's
/// authority and each cell's credentials, `cN.toml`, issued as its staff
/// issue them (`vl gateway issue`).
fn issue_cells(vl: &Path, cells: usize) -> Result<std::path::PathBuf, BenchError> {
    let keys = std::env::temp_dir().join(format!("vl-bench-gateway-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&keys);
    for n in 0..cells {
        let name = format!("c{n}");
        let out = keys.join(format!("{name}.toml"));
        let issued = std::process::Command::new(vl)
            .args(["gateway", "issue", "--cell", &name, "--out"])
            .arg(&out)
            .arg("--keys")
            .arg(&keys)
            .stdout(std::process::Stdio::null())
            .output()
            .map_err(|e| BenchError::Trust(format!("cannot start {}: {e}", vl.display())))?;
        if !issued.status.success() {
            return Err(BenchError::Trust(
                String::from_utf8_lossy(&issued.stderr).trim().to_owned(),
            ));
        }
    }
    Ok(keys)
}

/// A UDP port nothing listens on now, for the gateway's Zenoh router
/// (QUIC).
fn free_udp_port() -> Result<u16, BenchError> {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .map_err(|e| BenchError::Connect(e.to_string()))
}

/// Operators teleoperating at each of `urls`, all at once.
async fn operators(urls: &[String]) -> Result<Vec<Operator>, BenchError> {
    let mut joining = JoinSet::new();
    for url in urls {
        let url = url.clone();
        joining.spawn(async move { teleoperating(&url, None).await });
    }
    let mut operators = Vec::new();
    while let Some(joined) = joining.join_next().await {
        operators.push((joined.map_err(|e| BenchError::Connect(e.to_string()))??, 1));
    }
    Ok(operators)
}

/// Operators at each of `urls`, one after another: each is given a cell
/// before the next asks.
async fn operators_one_by_one(urls: &[String]) -> Result<Vec<Operator>, BenchError> {
    let mut operators = Vec::new();
    for url in urls {
        operators.push((teleoperating(url, None).await?, 1));
    }
    Ok(operators)
}

async fn say_bye(operators: Vec<Operator>) {
    for (mut operator, _) in operators {
        let _ = say(&mut operator, &GuestMessage::Bye).await;
    }
}

/// An operator, and the event its next command is.
type Operator = (Socket, u64);

/// Every operator times `commands` at once; the round's figures.
async fn round(
    operators: Vec<Operator>,
    commands: usize,
    pids: &Pids,
) -> Result<(Round, Vec<Operator>), BenchError> {
    let cpu = |pid: &u32| cpu_seconds(*pid);
    let (cells_before, gateway_before) = (
        pids.cells.iter().map(cpu).collect::<Vec<_>>(),
        cpu(&pids.gateway),
    );
    let wall = Instant::now();
    let mut timing = JoinSet::new();
    for (mut operator, event) in operators {
        timing.spawn(async move {
            // Each operator's events go on from where its run stands.
            let took = time_commands(&mut operator, event, commands, || false).await;
            took.map(|took| {
                let next = event + took.len() as u64;
                (took, (operator, next))
            })
        });
    }
    let (mut took, mut operators) = (Vec::new(), Vec::new());
    while let Some(timed) = timing.join_next().await {
        let (times, operator) = timed.map_err(|e| BenchError::Connect(e.to_string()))??;
        took.extend(times);
        operators.push(operator);
    }
    let seconds = wall.elapsed().as_secs_f64();
    let cells: Vec<f64> = pids
        .cells
        .iter()
        .zip(cells_before)
        .map(|(pid, before)| (cpu(pid) - before) / seconds)
        .collect();
    took.sort_by(f64::total_cmp);
    let q = |p: f64| nearest_rank(&took, p).unwrap_or(f64::NAN);
    let round = Round {
        p50_ms: q(0.5),
        p99_ms: q(0.99),
        cells_cores: cells.iter().sum(),
        busiest_cell_cores: cells.iter().copied().fold(0.0, f64::max),
        gateway_cores: (cpu(&pids.gateway) - gateway_before) / seconds,
    };
    Ok((round, operators))
}

/// Waits (a minute at most) until the gateway's `/status` pleases `done`.
async fn until_status(
    url: &str,
    done: impl Fn(&serde_json::Value) -> bool,
) -> Result<(), BenchError> {
    let authority = url
        .trim_start_matches("ws://")
        .trim_end_matches('/')
        .to_owned();
    let began = Instant::now();
    loop {
        let mut tcp = tokio::net::TcpStream::connect(&authority)
            .await
            .map_err(|e| BenchError::Connect(e.to_string()))?;
        let ask = format!("GET /status HTTP/1.1\r\nHost: {authority}\r\nConnection: close\r\n\r\n");
        tcp.write_all(ask.as_bytes())
            .await
            .map_err(|e| BenchError::Connect(e.to_string()))?;
        let mut answer = String::new();
        let _ = tcp.read_to_string(&mut answer).await;
        let body = answer.split_once("\r\n\r\n").map_or("", |(_, b)| b);
        if serde_json::from_str(body).is_ok_and(|s| done(&s)) {
            return Ok(());
        }
        if began.elapsed() > Duration::from_secs(60) {
            return Err(BenchError::Timeout(
                Duration::from_secs(60),
                "see the cells at the gateway",
            ));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

impl Report for GatewayCost {
    fn table(&self) -> Table {
        let round = |r: &Round| {
            format!(
                "p50 {:.2} ms, p99 {:.2} ms; cells {:.2} cores (busiest {:.2}), gateway {:.2} cores",
                r.p50_ms, r.p99_ms, r.cells_cores, r.busiest_cell_cores, r.gateway_cores
            )
        };
        Table::pairs([
            ("cells", format!("{}, an operator on each", self.cells)),
            (
                "commands timed",
                format!("{} by each operator a round", self.commands),
            ),
            ("straight to the cells", round(&self.direct)),
            ("through the gateway", round(&self.through)),
            (
                "through the gateway, watched",
                format!("{} ({} watchers)", round(&self.watched), self.watchers),
            ),
            (
                "the gateway adds to p99",
                format!("{:.2} ms", self.added_p99_ms),
            ),
            (
                "frames to each watcher",
                format!(
                    "{:.1} /s the slowest, {:.1} /s the median",
                    self.frames_hz_min, self.frames_hz_median
                ),
            ),
            (
                "the gateway to its watchers",
                format!("{:.1} MB/s", self.to_watchers_mb_s),
            ),
        ])
    }
}
