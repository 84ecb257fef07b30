//! What recording every run costs the lab: two simulated Hosts on the same
//! machine, one recording its runs and one not, each with an operator
//! teleoperating and the camera streaming at 15 fps. Rounds of timed
//! commands alternate between them (so both see the same load), then both
//! idle together while their feedback's period is read; the recording
//! Host's run then ends, and its file's size is taken.

use std::net::SocketAddr;
use std::time::Duration;

use serde::Serialize;
use vl_core::{Arena, Feedback, GuestMessage, HostMessage, nearest_rank};

use super::{BenchError, Socket, say, teleoperating, time_commands, until};
use crate::{Host, HostConfig, SimLab};
use vl_record::Catalogue;

/// Rounds of commands on each Host, alternating: finely interleaved, the
/// two see the same moments of the machine's load.
const ROUNDS: usize = 10;
/// How long both Hosts idle while their feedback's period is read: long
/// enough for a p99 of some 750 gaps each.
const IDLE: Duration = Duration::from_secs(15);

/// Recording on against off, in one run.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingCost {
    pub commands: usize,
    pub on_p99_ms: f64,
    pub off_p99_ms: f64,
    pub p99_ratio: f64,
    /// The control loop's period, as the gaps between its feedback while
    /// no command comes (it publishes every 20 ms), p99.
    pub on_period_p99_ms: f64,
    pub off_period_p99_ms: f64,
    pub period_ratio: f64,
    /// The recording's size per minute of run, at 15 frames a second.
    pub mb_per_minute: f64,
    pub dropped_frames: u64,
}

impl std::fmt::Display for RecordingCost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "recording on/off: command p99 {:.2}/{:.2} ms ({:.2}×), control period p99 {:.2}/{:.2} ms ({:.2}×); {:.1} MB a minute of run at 15 fps, {} frames dropped",
            self.on_p99_ms,
            self.off_p99_ms,
            self.p99_ratio,
            self.on_period_p99_ms,
            self.off_period_p99_ms,
            self.period_ratio,
            self.mb_per_minute,
            self.dropped_frames
        )
    }
}

/// Starts a simulated Host on the open arena, recording into `catalogue`.
async fn host(catalogue: Option<Catalogue>) -> Result<Host, BenchError> {
    let listen: SocketAddr = ([127, 0, 0, 1], 0).into();
    let lab = SimLab::new(Arena::named("open").expect("the open arena ships with vl"));
    let config = HostConfig {
        recordings: catalogue,
        ..HostConfig::default()
    };
    Ok(Host::start_sim(listen, lab, config).await?)
}

/// The gaps between the feedback `operator` reads for `IDLE`, ms, sorted.
async fn periods(operator: &mut Socket) -> Result<Vec<f64>, BenchError> {
    let deadline = std::time::Instant::now() + IDLE;
    let (mut gaps, mut last) = (Vec::new(), None);
    while std::time::Instant::now() < deadline {
        let t = until(operator, "read feedback", |m| match m {
            HostMessage::Feedback(Feedback { t_ms, .. }) => Some(*t_ms),
            _ => None,
        })
        .await?;
        if let Some(last) = last {
            gaps.push(t - last);
        }
        last = Some(t);
    }
    gaps.sort_by(f64::total_cmp);
    Ok(gaps)
}

pub(super) async fn recording_cost(commands: usize) -> Result<RecordingCost, BenchError> {
    let dir = std::env::temp_dir().join(format!("vl-bench-recordings-{}", std::process::id()));
    let catalogue = Catalogue::open(&dir).map_err(|e| BenchError::Connect(e.to_string()))?;
    let (on_host, off_host) = (host(Some(catalogue)).await?, host(None).await?);
    let mut on = teleoperating(&on_host.url(), None).await?;
    let mut off = teleoperating(&off_host.url(), None).await?;
    let (mut on_took, mut off_took) = (Vec::new(), Vec::new());
    let (mut on_event, mut off_event) = (1, 1);
    let per_round = commands.div_ceil(ROUNDS);
    for _ in 0..ROUNDS {
        let took = time_commands(&mut on, on_event, per_round, || false).await?;
        on_event += took.len() as u64;
        on_took.extend(took);
        let took = time_commands(&mut off, off_event, per_round, || false).await?;
        off_event += took.len() as u64;
        off_took.extend(took);
    }
    let (on_gaps, off_gaps) = tokio::join!(periods(&mut on), periods(&mut off));
    let (on_gaps, off_gaps) = (on_gaps?, off_gaps?);
    say(&mut on, &GuestMessage::Stop).await?;
    let summary = until(&mut on, "end the recorded run", |m| match m {
        HostMessage::Done { summary } => Some(summary.clone()),
        _ => None,
    })
    .await?;
    // The file is whole once the recorder has closed it.
    drop((on_host, off_host));
    tokio::time::sleep(Duration::from_millis(500)).await;
    let bytes = summary
        .recording
        .as_ref()
        .and_then(|r| std::fs::metadata(dir.join(r.name.as_str())).ok())
        .map_or(0, |m| m.len());
    let _ = std::fs::remove_dir_all(&dir);
    on_took.sort_by(f64::total_cmp);
    off_took.sort_by(f64::total_cmp);
    let p99 = |v: &[f64]| nearest_rank(v, 0.99).unwrap_or(f64::NAN);
    Ok(RecordingCost {
        commands: on_took.len(),
        on_p99_ms: p99(&on_took),
        off_p99_ms: p99(&off_took),
        p99_ratio: p99(&on_took) / p99(&off_took),
        on_period_p99_ms: p99(&on_gaps),
        off_period_p99_ms: p99(&off_gaps),
        period_ratio: p99(&on_gaps) / p99(&off_gaps),
        mb_per_minute: bytes as f64 / 1e6 / (summary.seconds / 60.0),
        dropped_frames: summary.recording.map_or(0, |r| r.dropped_frames),
    })
}
