//! What the relay costs by itself, and whether it gives real messages the
//! delays its model says. An echo server's round trips are timed straight
//! and through a zero-delay relay, taken in turn; then through each
//! profile, on several connections at once, against the same-seeded model
//! run in virtual time on the same send times (connection k's links are
//! seeded `seed + 2k` and `seed + 2k + 1`, as the relay numbers them in the
//! order they connect).

use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde::Serialize;
use tokio::net::TcpListener;
use tokio_tungstenite::tungstenite::Message;
use vl_report::table::{Report, Table};
use vl_sim::{Delivery, LinkModel, MessageLink};

use super::{Media, MediaConfig};

/// Connections measured at once per profile, and how long each sends for.
const CONNECTIONS: u64 = 8;
const SENDING: Duration = Duration::from_secs(5);
/// How often each connection sends: ten round trips apart, so TCP's order
/// rarely holds a message behind the one before, but at least 10 ms (a
/// fast link gets more messages, which its small jitter needs to be told
/// from the measurement's noise) and at most 100 ms.
fn interval(model: &LinkModel) -> Duration {
    Duration::from_secs_f64((20.0 * model.delay_ms).clamp(10.0, 100.0) / 1e3)
}
/// The relays' seed.
const SEED: u64 = 11;
/// The timed messages' size, bytes.
const MESSAGE_BYTES: usize = 100;

/// Round-trip percentiles, ms.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RelayRoundTrip {
    pub p50_ms: f64,
    pub p99_ms: f64,
}

impl RelayRoundTrip {
    fn of(mut ms: Vec<f64>) -> RelayRoundTrip {
        ms.sort_by(f64::total_cmp);
        let at = |q: f64| vl_core::nearest_rank(&ms, q).unwrap_or(f64::NAN);
        RelayRoundTrip {
            p50_ms: at(0.5),
            p99_ms: at(0.99),
        }
    }
}

/// One profile's round trips through the relay against its model, ms.
#[derive(Debug, Clone, Serialize)]
pub struct Reproduced {
    pub profile: String,
    pub messages: usize,
    pub model_mean_ms: f64,
    pub model_sd_ms: f64,
    /// What the relay added by its model: its own zero-delay cost taken
    /// away (the mean subtracted, the variance too).
    pub relay_mean_ms: f64,
    pub relay_sd_ms: f64,
    /// How far each round trip was from its own model's, beyond the mean
    /// offset (the deviation of measured − modelled): the relay's timing
    /// and the measurement's noise together.
    pub timing_sd_ms: f64,
    /// The part of the measured round trips' spread that follows the
    /// model message by message: the slope of measured on modelled times
    /// the model's sd. Noise that has nothing to do with the model
    /// averages out of it, so it resolves a jitter smaller than the
    /// machine's timing noise.
    pub tracked_sd_ms: f64,
    /// Its standard error: timing sd / √messages.
    pub tracked_se_ms: f64,
    /// Messages left out of the tracked sd: their round trip was more than
    /// [`HICCUP`] off its model's beyond the usual offset (the machine
    /// paused the measurement; the model's own spread is far smaller).
    pub hiccups: usize,
    /// The zero-delay relay's round trip on this profile's traffic.
    pub own_mean_ms: f64,
    pub own_sd_ms: f64,
}

/// What the relay costs, and how closely it keeps to its model.
#[derive(Debug, Clone, Serialize)]
pub struct MediaBench {
    pub messages: usize,
    pub direct: RelayRoundTrip,
    pub relayed: RelayRoundTrip,
    /// Relayed minus direct, at each percentile.
    pub added: RelayRoundTrip,
    pub profiles: Vec<Reproduced>,
}

/// Why the Media's bench could not measure.
#[derive(Debug, thiserror::Error)]
pub enum MediaBenchError {
    #[error("the bench's echo server cannot listen")]
    Echo(#[source] std::io::Error),
    #[error("the bench's relay does not start")]
    Relay(#[source] super::MediaError),
    #[error("the bench cannot reach {url}")]
    Connect {
        url: String,
        #[source]
        source: tokio_tungstenite::tungstenite::Error,
    },
    #[error("the bench cannot send")]
    Send(#[source] tokio_tungstenite::tungstenite::Error),
    #[error("{0} ended a connection mid-bench")]
    Ended(&'static str),
}

/// An echo server on a free port: every text message goes straight back.
async fn echo() -> Result<(String, tokio::task::JoinHandle<()>), MediaBenchError> {
    let listener = TcpListener::bind(("127.0.0.1", 0))
        .await
        .map_err(MediaBenchError::Echo)?;
    let url = format!(
        "ws://{}",
        listener.local_addr().map_err(MediaBenchError::Echo)?
    );
    let server = tokio::spawn(async move {
        while let Ok((stream, _)) = listener.accept().await {
            let _ = stream.set_nodelay(true);
            tokio::spawn(async move {
                let Ok(mut ws) = tokio_tungstenite::accept_async(stream).await else {
                    return;
                };
                while let Some(Ok(m)) = ws.next().await {
                    if m.is_text() && ws.send(m).await.is_err() {
                        return;
                    }
                }
            });
        }
    });
    Ok((url, server))
}

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(url: &str) -> Result<Socket, MediaBenchError> {
    tokio_tungstenite::connect_async_with_config(url, None, true)
        .await
        .map(|(ws, _)| ws)
        .map_err(|source| MediaBenchError::Connect {
            url: url.to_owned(),
            source,
        })
}

/// Sends `text` and waits for it to come back.
async fn round_trip(ws: &mut Socket, text: &Message) -> Result<f64, MediaBenchError> {
    let sent = Instant::now();
    ws.send(text.clone()).await.map_err(MediaBenchError::Send)?;
    loop {
        match ws.next().await {
            Some(Ok(m)) if m.is_text() => return Ok(sent.elapsed().as_secs_f64() * 1e3),
            Some(Ok(_)) => {}
            _ => return Err(MediaBenchError::Ended("the echo")),
        }
    }
}

fn relay(upstream: &str, model: LinkModel) -> MediaConfig {
    MediaConfig {
        upstream: upstream.to_owned(),
        model,
        seed: SEED,
    }
}

fn zero() -> LinkModel {
    LinkModel {
        delay_ms: 0.0,
        jitter_ms: 0.0,
        ..LinkModel::profile(vl_sim::Profile::Lan)
    }
}

/// Each connection's (send time ms from the first send, round trip ms)
/// through the relay at `url`, one message every `interval` for
/// [`SENDING`].
async fn trips(url: &str, interval: Duration) -> Result<Vec<Vec<(f64, f64)>>, MediaBenchError> {
    let per_connection = (SENDING.as_secs_f64() / interval.as_secs_f64()) as usize;
    let mut sockets = Vec::new();
    // One at a time, so the relay numbers them in this order.
    for _ in 0..CONNECTIONS {
        sockets.push(connect(url).await?);
    }
    let epoch = Instant::now();
    let text = Message::text("x".repeat(MESSAGE_BYTES));
    // Connection k sends k/8 of an interval after the first: one message
    // at a time, so what is timed is the link, not a burst's queueing.
    let runs = (0u32..).zip(sockets).map(|(k, ws)| {
        let text = text.clone();
        let offset = interval * k / CONNECTIONS as u32;
        async move {
            let (mut sink, mut source) = ws.split();
            let sender = async {
                let mut sent = Vec::new();
                for i in 0..per_connection {
                    tokio::time::sleep_until((epoch + offset + interval * i as u32).into()).await;
                    sent.push(epoch.elapsed().as_secs_f64() * 1e3);
                    sink.send(text.clone())
                        .await
                        .map_err(MediaBenchError::Send)?;
                }
                Ok::<_, MediaBenchError>(sent)
            };
            let receiver = async {
                let mut back = Vec::new();
                while back.len() < per_connection {
                    match source.next().await {
                        Some(Ok(m)) if m.is_text() => {
                            back.push(epoch.elapsed().as_secs_f64() * 1e3)
                        }
                        Some(Ok(_)) => {}
                        _ => return Err(MediaBenchError::Ended("the relay")),
                    }
                }
                Ok(back)
            };
            let (sent, back) = tokio::join!(sender, receiver);
            let (sent, back) = (sent?, back?);
            Ok::<_, MediaBenchError>(sent.iter().zip(&back).map(|(s, b)| (*s, b - s)).collect())
        }
    });
    futures_util::future::join_all(runs)
        .await
        .into_iter()
        .collect()
}

/// Each of `measured`'s round trips beside what the model says it is, on
/// the same send times: (measured, modelled).
fn modelled(model: &LinkModel, measured: &[Vec<(f64, f64)>]) -> Vec<(f64, f64)> {
    let mut all = Vec::new();
    for (k, pings) in (0u64..).zip(measured) {
        let mut up = MessageLink::new(model.clone(), SEED + 2 * k);
        let mut down = MessageLink::new(model.clone(), SEED + 2 * k + 1);
        for &(sent, rtt) in pings {
            if let Delivery::At(there) = up.send(sent, MESSAGE_BYTES)
                && let Delivery::At(back) = down.send(there, MESSAGE_BYTES)
            {
                all.push((rtt, back - sent));
            }
        }
    }
    all
}

/// How far a round trip may be from its model's, beyond the median
/// offset, and still count toward the tracked sd.
const HICCUP: f64 = 1.0;

/// The tracked sd of `pairs` (measured, modelled) and its standard error,
/// the slope fitted leaving out hiccups (`apart` is measured − modelled);
/// and how many were left out. Which messages are left out does not
/// depend on the model's value, so leaving them out does not bend the
/// slope toward 1.
fn tracked(pairs: &[(f64, f64)], apart: &[f64]) -> (f64, f64, usize) {
    let model_sd = mean_sd(&pairs.iter().map(|p| p.1).collect::<Vec<_>>()).1;
    let mut sorted = apart.to_vec();
    sorted.sort_by(f64::total_cmp);
    let offset = vl_core::nearest_rank(&sorted, 0.5).unwrap_or(0.0);
    let kept: Vec<(f64, f64)> = pairs
        .iter()
        .zip(apart)
        .filter(|(_, a)| (*a - offset).abs() <= HICCUP)
        .map(|(p, _)| *p)
        .collect();
    let measured: Vec<f64> = kept.iter().map(|p| p.0).collect();
    let modelled: Vec<f64> = kept.iter().map(|p| p.1).collect();
    let kept_apart: Vec<f64> = kept.iter().map(|p| p.0 - p.1).collect();
    let ((got_mean, _), (want_mean, want_sd)) = (mean_sd(&measured), mean_sd(&modelled));
    let n = kept.len().max(1) as f64;
    let covariance = kept
        .iter()
        .map(|(got, want)| (got - got_mean) * (want - want_mean))
        .sum::<f64>()
        / n;
    // The slope's standard error is timing sd / (sd(modelled) √n).
    let scale = model_sd / want_sd;
    (
        covariance / (want_sd * want_sd) * model_sd,
        mean_sd(&kept_apart).1 / n.sqrt() * scale,
        pairs.len() - kept.len(),
    )
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    (
        mean,
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt(),
    )
}

fn rtts(trips: Vec<Vec<(f64, f64)>>) -> Vec<f64> {
    trips.into_iter().flatten().map(|(_, rtt)| rtt).collect()
}

/// Times `messages` round trips straight and through a zero-delay relay,
/// in turn; then each of `profiles` (named) against its model.
pub async fn bench(
    messages: usize,
    profiles: &[(String, LinkModel)],
) -> Result<MediaBench, MediaBenchError> {
    let (echo_url, server) = echo().await?;
    let own_relay = Media::start(([127, 0, 0, 1], 0).into(), relay(&echo_url, zero()))
        .await
        .map_err(MediaBenchError::Relay)?;
    let mut direct_ws = connect(&echo_url).await?;
    let mut relayed_ws = connect(&own_relay.url()).await?;
    let (mut direct, mut relayed) = (Vec::new(), Vec::new());
    let text = Message::text("x".repeat(MESSAGE_BYTES));
    let messages = messages.max(1);
    for _ in 0..messages {
        direct.push(round_trip(&mut direct_ws, &text).await?);
        relayed.push(round_trip(&mut relayed_ws, &text).await?);
    }
    let (direct, relayed) = (RelayRoundTrip::of(direct), RelayRoundTrip::of(relayed));
    let mut reproduced = Vec::new();
    for (name, model) in profiles {
        // The relay's own cost on this profile's traffic, from a fresh
        // relay (the relay numbers connections from 0).
        let own = Media::start(([127, 0, 0, 1], 0).into(), relay(&echo_url, zero()))
            .await
            .map_err(MediaBenchError::Relay)?;
        let (own_mean_ms, own_sd_ms) = mean_sd(&rtts(trips(&own.url(), interval(model)).await?));
        let media = Media::start(([127, 0, 0, 1], 0).into(), relay(&echo_url, model.clone()))
            .await
            .map_err(MediaBenchError::Relay)?;
        let pairs = modelled(model, &trips(&media.url(), interval(model)).await?);
        let all: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let expected: Vec<f64> = pairs.iter().map(|p| p.1).collect();
        let apart: Vec<f64> = pairs.iter().map(|p| p.0 - p.1).collect();
        let (model_mean_ms, model_sd_ms) = mean_sd(&expected);
        let (mean, sd) = mean_sd(&all);
        let timing_sd_ms = mean_sd(&apart).1;
        let (tracked_sd_ms, tracked_se_ms, hiccups) = tracked(&pairs, &apart);
        reproduced.push(Reproduced {
            profile: name.clone(),
            messages: all.len(),
            model_mean_ms,
            model_sd_ms,
            relay_mean_ms: mean - own_mean_ms,
            relay_sd_ms: (sd * sd - own_sd_ms * own_sd_ms).max(0.0).sqrt(),
            timing_sd_ms,
            tracked_sd_ms,
            tracked_se_ms,
            hiccups,
            own_mean_ms,
            own_sd_ms,
        });
    }
    server.abort();
    Ok(MediaBench {
        messages,
        added: RelayRoundTrip {
            p50_ms: relayed.p50_ms - direct.p50_ms,
            p99_ms: relayed.p99_ms - direct.p99_ms,
        },
        direct,
        relayed,
        profiles: reproduced,
    })
}

impl Report for MediaBench {
    fn table(&self) -> Table {
        let mut table = Table::columns(&[
            "profile",
            "model rtt",
            "relay rtt",
            "ratio",
            "model sd",
            "relay sd",
            "ratio",
            "tracked sd",
            "ratio",
            "timing sd",
            "hiccups",
            "own rtt",
        ]);
        for p in &self.profiles {
            table.row(vec![
                p.profile.clone(),
                format!("{:.3}", p.model_mean_ms),
                format!("{:.3}", p.relay_mean_ms),
                format!("{:.3}", p.relay_mean_ms / p.model_mean_ms),
                format!("{:.3}", p.model_sd_ms),
                format!("{:.3}", p.relay_sd_ms),
                format!("{:.3}", p.relay_sd_ms / p.model_sd_ms),
                format!("{:.3} ± {:.3}", p.tracked_sd_ms, p.tracked_se_ms),
                format!("{:.3}", p.tracked_sd_ms / p.model_sd_ms),
                format!("{:.3}", p.timing_sd_ms),
                p.hiccups.to_string(),
                format!("{:.3} ± {:.3}", p.own_mean_ms, p.own_sd_ms),
            ]);
        }
        let (d, r, a) = (self.direct, self.relayed, self.added);
        table
            .title(format!(
                "the relay's own cost, {} round trips each way, taken in turn (p50 / p99 ms): \
                 straight {:.3} / {:.3}, through a zero-delay relay {:.3} / {:.3}, added {:.3} / {:.3}",
                self.messages, d.p50_ms, d.p99_ms, r.p50_ms, r.p99_ms, a.p50_ms, a.p99_ms
            ))
            .title("each profile's round trip through the relay (its own cost taken away) against the same-seeded model on the same send times, ms:")
            .note(
                "8 connections for 5 s per profile, one message in flight on each; relay sd: the measured spread less \
                 the zero-delay relay's (own rtt, mean ± sd, on the same traffic); tracked sd: the part of the spread \
                 that follows the model message by message (± its standard error), leaving out hiccups: round trips more than 1 ms off their model's beyond \
                 the usual offset; timing sd: each round trip \
                 against its own model's, beyond the mean offset",
            )
    }
}
