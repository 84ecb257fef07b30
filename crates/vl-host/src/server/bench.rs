//! How soon an operator's command is answered: a simulated Host with its
//! camera streaming, many observers reading everything it sends, and one
//! operator under event-based control, who sends command s + 1 as soon as
//! the feedback of command s arrives. Each command's time to the feedback
//! of its event is what the operator's loop waits for.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde::Serialize;
use tokio::task::JoinSet;
use tokio_tungstenite::tungstenite::Message;
use vl_core::{
    Arena, Drive, Feedback, GuestMessage, HostMessage, PROTOCOL_VERSION, Role, RunComponent,
    Secret, Wire, nearest_rank,
};
use vl_report::table::{Report, Table};

use super::hub::ForecastJob;

mod gateway;
mod guessing;
mod recording;
mod watchers;
use crate::accounts::users::{AccountRole, Users};
use crate::{ForecastSettings, Host, HostConfig, SimLab};
pub use gateway::{GatewayBench, GatewayCost};
pub use guessing::Guessing;
pub use watchers::{WatchersBench, WatchersCost};

/// Why the bench could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("cannot start the simulated Host: {0}")]
    Host(#[from] crate::HostError),
    #[error("cannot connect to the Host: {0}")]
    Connect(String),
    #[error("the Host refused to {step}: {message}")]
    Refused { step: &'static str, message: String },
    #[error("the connection ended while waiting to {0}")]
    Closed(&'static str),
    #[error("no answer within {0:?} while waiting to {1}")]
    Timeout(Duration, &'static str),
    #[error("cannot start the guessers' runtime: {0}")]
    Runtime(std::io::Error),
    #[error("cannot issue the cells' credentials: {0}")]
    Trust(String),
    #[error("the Host offers no experiment driven by stick")]
    NoStick,
}

/// Command → feedback of its event, ms, and what the observers got.
#[derive(Debug, Clone, Serialize)]
pub struct OperatorLatency {
    pub observers: usize,
    pub commands: usize,
    pub p50_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    /// Feedback messages the slowest-fed observer read per second.
    pub observer_feedback_hz: f64,
    /// Camera frames the slowest-fed observer read per second.
    pub observer_frames_hz: f64,
    /// The same commands again while one address tries wrong passwords.
    pub under_guessing: Guessing,
    /// The same commands again while the machine forecasts definitions.
    pub while_forecasting: WhileForecasting,
    /// A Host that records its runs against one that does not.
    pub recording: recording::RecordingCost,
}

/// The operator's round trips while the Host forecasts a minute's
/// navigation run over and over, as its forecast worker would for a
/// definition given again as soon as each verdict came (here beside a
/// teleoperation run, which a Host's own forecasts never are), against a
/// quiet round after each such round.
#[derive(Debug, Clone, Serialize)]
pub struct WhileForecasting {
    #[serde(flatten)]
    pub timed: AgainstQuiet,
    /// Forecasts made while the commands were timed.
    pub forecasts: u64,
}

/// Round trips timed under some load, pooled over its rounds, against the
/// quiet rounds between them.
#[derive(Debug, Clone, Serialize)]
pub struct AgainstQuiet {
    /// Commands timed under the load.
    pub commands: usize,
    pub p50_ms: f64,
    pub p99_ms: f64,
    /// The quiet rounds after each loaded one.
    pub quiet_p50_ms: f64,
    pub quiet_p99_ms: f64,
    /// The loaded rounds' p99 over the quiet rounds'.
    pub p99_ratio: f64,
}

impl AgainstQuiet {
    fn of(mut loaded: Vec<f64>, mut quiet: Vec<f64>) -> AgainstQuiet {
        loaded.sort_by(f64::total_cmp);
        quiet.sort_by(f64::total_cmp);
        let q = |took: &[f64], p| nearest_rank(took, p).unwrap_or(f64::NAN);
        AgainstQuiet {
            commands: loaded.len(),
            p50_ms: q(&loaded, 0.5),
            p99_ms: q(&loaded, 0.99),
            quiet_p50_ms: q(&quiet, 0.5),
            quiet_p99_ms: q(&quiet, 0.99),
            p99_ratio: q(&loaded, 0.99) / q(&quiet, 0.99),
        }
    }
}

/// Rounds of load (floods of wrong passwords, forecasts), each followed
/// by a quiet round.
const FLOODS: usize = 4;

/// The bench's one account, whose operator it times.
const ACCOUNT: (&str, &str) = ("bench", "bench password");

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// A `vl` child process (a Host, a gateway), killed when dropped.
struct Process(std::process::Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Process {
    /// Starts `vl ARGS…`; it, and the rest of its first line after
    /// `prefix` (where it listens).
    fn start(
        vl: &std::path::Path,
        args: &[&str],
        prefix: &str,
    ) -> Result<(Process, String), BenchError> {
        use std::io::BufRead;
        let child = std::process::Command::new(vl)
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .map_err(|e| BenchError::Connect(format!("cannot start {}: {e}", vl.display())))?;
        let mut process = Process(child);
        let stdout = process.0.stdout.take().expect("piped stdout");
        let mut line = String::new();
        std::io::BufReader::new(stdout)
            .read_line(&mut line)
            .map_err(|e| BenchError::Connect(e.to_string()))?;
        let rest = line
            .trim()
            .strip_prefix(prefix)
            .ok_or_else(|| BenchError::Connect(format!("vl {} said {line:?}", args[0])))?
            .to_owned();
        Ok((process, rest))
    }

    fn pid(&self) -> u32 {
        self.0.id()
    }
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

/// How long any one answer may take.
const ANSWER: Duration = Duration::from_secs(10);

async fn connect(url: &str) -> Result<Socket, BenchError> {
    tokio_tungstenite::connect_async(url)
        .await
        .map(|(ws, _)| ws)
        .map_err(|e| BenchError::Connect(e.to_string()))
}

async fn say(ws: &mut Socket, message: &GuestMessage) -> Result<(), BenchError> {
    ws.send(Message::text(message.encode()))
        .await
        .map_err(|e| BenchError::Connect(e.to_string()))
}

/// The next text message that `pick` takes, answering pings meanwhile; an
/// `error` that `pick` does not take ends the wait.
async fn until<T>(
    ws: &mut Socket,
    step: &'static str,
    mut pick: impl FnMut(&HostMessage) -> Option<T>,
) -> Result<T, BenchError> {
    let deadline = tokio::time::Instant::now() + ANSWER;
    loop {
        let next = tokio::time::timeout_at(deadline, ws.next())
            .await
            .map_err(|_| BenchError::Timeout(ANSWER, step))?;
        let Some(Ok(Message::Text(text))) = next else {
            match next {
                None | Some(Err(_)) => return Err(BenchError::Closed(step)),
                _ => continue,
            }
        };
        let Ok(message) = HostMessage::decode(text.as_str()) else {
            continue;
        };
        if let Some(found) = pick(&message) {
            return Ok(found);
        }
        match message {
            HostMessage::Ping { t } => say(ws, &GuestMessage::Pong { t }).await?,
            HostMessage::Error { message, .. } => {
                return Err(BenchError::Refused { step, message });
            }
            _ => {}
        }
    }
}

fn hello(role: Role, password: Option<&str>) -> GuestMessage {
    GuestMessage::Hello {
        protocol: PROTOCOL_VERSION,
        role,
        token: None,
        resume: None,
        user: password.map(|_| ACCOUNT.0.to_owned()),
        password: password.map(|p| Secret(p.to_owned())),
        session: None,
    }
}

/// An observer, welcomed: one at a time, as the Host admits only a few
/// not yet welcomed from one address.
async fn observer(url: &str) -> Result<Socket, BenchError> {
    let mut ws = connect(url).await?;
    say(&mut ws, &hello(Role::Observer, None)).await?;
    until(&mut ws, "watch", |m| {
        matches!(m, HostMessage::Welcome { .. }).then_some(())
    })
    .await?;
    Ok(ws)
}

/// What an observer read, and over how many seconds.
#[derive(Debug, Clone, Copy, Default)]
struct Observed {
    feedback: u64,
    frames: u64,
    /// Of messages, text and frames alike.
    bytes: u64,
    seconds: f64,
}

/// Reads everything until told to stop, then says goodbye.
async fn observe(mut ws: Socket, mut stop: tokio::sync::watch::Receiver<bool>) -> Observed {
    let began = Instant::now();
    let (mut feedback, mut frames, mut bytes) = (0, 0, 0);
    loop {
        tokio::select! {
            _ = stop.changed() => break,
            next = ws.next() => match next {
                Some(Ok(Message::Text(text))) => {
                    bytes += text.len() as u64;
                    match HostMessage::decode(text.as_str()) {
                        Ok(HostMessage::Feedback(_)) => feedback += 1,
                        Ok(HostMessage::Ping { t }) => {
                            let _ = say(&mut ws, &GuestMessage::Pong { t }).await;
                        }
                        _ => {}
                    }
                }
                Some(Ok(Message::Binary(frame))) => {
                    frames += 1;
                    bytes += frame.len() as u64;
                }
                Some(Ok(_)) => {}
                _ => break,
            },
        }
    }
    let _ = say(&mut ws, &GuestMessage::Bye).await;
    Observed {
        feedback,
        frames,
        bytes,
        seconds: began.elapsed().as_secs_f64(),
    }
}

/// Runs the bench on a Host with `extensions` plugged in (as `vl host`
/// has them): `observers` reading, `commands` timed; `step` is told each
/// stage as it begins (the whole takes minutes).
pub async fn operator_latency(
    observers: usize,
    commands: usize,
    extensions: Vec<std::sync::Arc<dyn crate::Extension>>,
    mut step: impl FnMut(&str),
) -> Result<OperatorLatency, BenchError> {
    step(&format!("a Host with {observers} observers watching"));
    let listen: SocketAddr = ([127, 0, 0, 1], 0).into();
    let lab = SimLab::new(Arena::named("open").expect("the open arena ships with vl"));
    let mut users = Users::default();
    users
        .add(ACCOUNT.0, AccountRole::Operator, ACCOUNT.1)
        .expect("a good account");
    let config = HostConfig {
        users: Some(users),
        extensions,
        ..HostConfig::default()
    };
    let host = Host::start_sim(listen, lab, config).await?;
    let url = host.url();
    let (stop_tx, stop) = tokio::sync::watch::channel(false);
    let mut watching = JoinSet::new();
    for _ in 0..observers {
        let ws = observer(&url).await?;
        watching.spawn(observe(ws, stop.clone()));
    }
    let mut operator = teleoperating(&url, Some(ACCOUNT.1)).await?;
    let began = Instant::now();
    step(&format!("timing {commands} commands"));
    let mut took = time_commands(&mut operator, 1, commands, || false).await?;
    // The next command's event, carried through the rounds.
    let mut event = took.len() as u64 + 1;
    step(&format!(
        "timing {commands} commands while passwords are guessed"
    ));
    let under_guessing = guessing::guessing(&mut operator, &url, &mut event, commands).await?;
    step(&format!(
        "timing {commands} commands while the twin forecasts"
    ));
    let while_forecasting = forecasting(&mut operator, &mut event, commands).await?;
    let _ = say(&mut operator, &GuestMessage::Bye).await;
    let _ = stop_tx.send(true);
    // The observers read from the first round to the last.
    let seconds = began.elapsed().as_secs_f64();
    let mut fed = Vec::new();
    while let Some(counts) = watching.join_next().await {
        fed.push(counts.unwrap_or_default());
    }
    drop(host);
    step(&format!(
        "timing {commands} commands while recording, and without"
    ));
    let recording = recording::recording_cost(commands).await?;
    took.sort_by(f64::total_cmp);
    let q = |p| nearest_rank(&took, p).unwrap_or(f64::NAN);
    let slowest = fed
        .iter()
        .map(|o| (o.feedback, o.frames))
        .min_by_key(|(f, _)| *f)
        .unwrap_or_default();
    Ok(OperatorLatency {
        observers,
        commands,
        p50_ms: q(0.5),
        p90_ms: q(0.9),
        p99_ms: q(0.99),
        max_ms: took.last().copied().unwrap_or(f64::NAN),
        observer_feedback_hz: slowest.0 as f64 / seconds,
        observer_frames_hz: slowest.1 as f64 / seconds,
        under_guessing,
        while_forecasting,
        recording,
    })
}

/// An operator on `url` (logged in with `password` to the bench's
/// account, if given) with a run started of the first experiment the Host
/// offers that is driven by stick.
async fn teleoperating(url: &str, password: Option<&str>) -> Result<Socket, BenchError> {
    let mut operator = connect(url).await?;
    say(&mut operator, &hello(Role::Operator, password)).await?;
    let experiments = until(&mut operator, "say hello", |m| match m {
        HostMessage::Welcome { experiments, .. } => Some(experiments.clone()),
        _ => None,
    })
    .await?;
    let driven = experiments
        .iter()
        .find(|e| e.run.has(RunComponent::Teleoperate));
    let mount = GuestMessage::Mount {
        experiment: driven.ok_or(BenchError::NoStick)?.id.to_string(),
    };
    say(&mut operator, &mount).await?;
    until(&mut operator, "mount", |m| {
        matches!(m, HostMessage::Mounted(_)).then_some(())
    })
    .await?;
    // The map's field is made on mount; start is allowed once it is.
    loop {
        say(&mut operator, &GuestMessage::Start).await?;
        let started = until(&mut operator, "start", |m| match m {
            HostMessage::Started { .. } => Some(true),
            HostMessage::Error { .. } => Some(false),
            _ => None,
        })
        .await?;
        if started {
            return Ok(operator);
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Times commands from event `first` on, each sent when the last one's
/// feedback came: at least `commands`, and on while `more` says so.
async fn time_commands(
    operator: &mut Socket,
    first: u64,
    commands: usize,
    more: impl Fn() -> bool,
) -> Result<Vec<f64>, BenchError> {
    let mut took = Vec::with_capacity(commands);
    let mut event = first;
    while took.len() < commands || more() {
        // Turning on the spot: the robot keeps clear of everything.
        let drive = Drive::Wheels {
            left: -40.0,
            right: 40.0,
        };
        let sent = Instant::now();
        let command = GuestMessage::Command {
            event,
            seen: Some(event - 1),
            drive,
        };
        say(operator, &command).await?;
        until(operator, "see a command's feedback", |m| match m {
            HostMessage::Feedback(Feedback { event: e, .. }) if *e >= event => Some(()),
            _ => None,
        })
        .await?;
        took.push(sent.elapsed().as_secs_f64() * 1e3);
        event += 1;
    }
    Ok(took)
}

/// The operator's commands from `event` on, timed while the Host
/// forecasts without pause, then in a quiet round, [`FLOODS`] times.
async fn forecasting(
    operator: &mut Socket,
    event: &mut u64,
    commands: usize,
) -> Result<WhileForecasting, BenchError> {
    // Rounds pooled as the floods are: a p99 of a few thousand trips is noisy.
    let (mut busy, mut quiet, mut forecasts) = (Vec::new(), Vec::new(), 0);
    for _ in 0..FLOODS {
        let stop = Arc::new(AtomicBool::new(false));
        let forecasting = forecaster(stop.clone());
        let took = time_commands(operator, *event, commands, || false).await?;
        stop.store(true, Ordering::Relaxed);
        forecasts += forecasting.join().unwrap_or(0);
        *event += took.len() as u64;
        busy.extend(took);
        let took = time_commands(operator, *event, commands, || false).await?;
        *event += took.len() as u64;
        quiet.extend(took);
    }
    Ok(WhileForecasting {
        timed: AgainstQuiet::of(busy, quiet),
        forecasts,
    })
}

/// The navigation arena's planned path at a speed that makes it a
/// minute's run: each forecast of it keeps a core busy a while.
fn minute_run() -> vl_core::Definition {
    let arena = Arena::navigation();
    let robot = vl_core::RobotModel::khepera_ii();
    let goal = arena.goal.unwrap_or(arena.start.point());
    let path = vl_core::plan_route(&arena, &[], &robot, arena.start, goal)
        .map(|plan| plan.points())
        .unwrap_or_default();
    vl_core::Definition {
        goal: Some(vl_core::Goal::at(goal)),
        path,
        max_speed_mm_s: Some(17.0),
        ..vl_core::Definition::default()
    }
}

/// Forecasts of a minute's run, one after another until `stop`, as the
/// Host's forecast worker makes them; how many were made.
fn forecaster(stop: Arc<AtomicBool>) -> std::thread::JoinHandle<u64> {
    let arena = Arena::navigation();
    let job = ForecastJob {
        start: arena.start,
        arena,
        robot: vl_core::RobotModel::khepera_ii(),
        definition: minute_run(),
        settings: ForecastSettings::default(),
        controller: None,
    };
    std::thread::spawn(move || {
        let mut made = 0;
        while job.run(&stop).is_ok() {
            made += 1;
        }
        made
    })
}

impl Report for OperatorLatency {
    fn table(&self) -> Table {
        let g = &self.under_guessing;
        let (t, f) = (&g.timed, &self.while_forecasting);
        Table::pairs([
            ("observers reading", self.observers.to_string()),
            ("commands timed", self.commands.to_string()),
            ("p50", format!("{:.2} ms", self.p50_ms)),
            ("p90", format!("{:.2} ms", self.p90_ms)),
            ("p99", format!("{:.2} ms", self.p99_ms)),
            ("max", format!("{:.2} ms", self.max_ms)),
            (
                "feedback to the slowest observer",
                format!("{:.1} /s", self.observer_feedback_hz),
            ),
            (
                "frames to the slowest observer",
                format!("{:.1} /s", self.observer_frames_hz),
            ),
            (
                "p99 under guessing",
                format!(
                    "{:.2} ms (p50 {:.2} ms) over {} commands in {FLOODS} floods: {:.2}× the quiet rounds'",
                    t.p99_ms, t.p50_ms, t.commands, t.p99_ratio
                ),
            ),
            (
                "p99 in the quiet rounds",
                format!(
                    "{:.2} ms (p50 {:.2} ms), one after each flood",
                    t.quiet_p99_ms, t.quiet_p50_ms
                ),
            ),
            (
                "wrong passwords",
                format!(
                    "{} sent from one address in {FLOODS} floods: {} checked, {} refused unchecked, {} pushed out unanswered",
                    g.sent, g.checked, g.limited, g.unanswered
                ),
            ),
            (
                "p99 while forecasting",
                format!(
                    "{:.2} ms (p50 {:.2} ms) over {} commands, {} forecasts of a minute's run made meanwhile: {:.2}× the quiet round's {:.2} ms",
                    f.timed.p99_ms,
                    f.timed.p50_ms,
                    f.timed.commands,
                    f.forecasts,
                    f.timed.p99_ratio,
                    f.timed.quiet_p99_ms
                ),
            ),
        ])
        .title("an operator's command to the feedback of its event, on loopback:")
        .note(self.recording.to_string())
    }
}
