//! The gateway: the lab's one public address in front of many cells. Its
//! connections are a Host's (pages, Guests, TLS, accounts, admission);
//! behind them, instead of a lab, the front (`front`) routes each Guest to
//! a cell and serves each cell's watchers from the one copy the cell
//! publishes (`mirror`).

mod event;
mod front;
mod mirror;

use std::sync::Arc;

use tokio::net::TcpListener;
use tokio::sync::{mpsc, watch};
use tracing::{error, info, warn};
use vl_core::CellName;
use zenoh::sample::SampleKind;

use super::{ZenohError, ZenohOptions, ZenohTrust, keys, within};
use event::Event;
use front::Front;
use vl_host::Hush;
use vl_host::LabEvents;
use vl_host::{Admission, HUB_QUEUE, HostConfig, LabHandle, accept, watch_accounts};

/// Connections a gateway serves at once: a class or several, watching
/// cells that each send every frame once.
const CONNECTIONS: usize = 4096;

/// Events from the cells waiting for the front.
const EVENTS: usize = 4096;

/// Serves Guests on `listener` and the cells met on Zenoh by `zenoh`,
/// until the task is dropped.
pub(crate) async fn serve(listener: TcpListener, config: HostConfig, zenoh: ZenohOptions) {
    let session = match super::open(&zenoh).await {
        Ok(session) => session,
        Err(e) => return error!("the gateway cannot open Zenoh: {e}"),
    };
    info!(zid = %session.zid(), "the gateway is on Zenoh");
    let config = Arc::new(config);
    // People an LMS launched here are let in as they are at a lone Host.
    let gate = Arc::new(vl_host::gate_of(&config));
    let (hub_tx, hub_rx) = mpsc::channel(HUB_QUEUE);
    let (events_tx, events_rx) = mpsc::channel(EVENTS);
    // A gateway's connections are given their cell's feedback and frames
    // on their welcome; until then, nothing.
    let (_no_feedback, feedback) = watch::channel(None);
    let (_no_frames, frames) = watch::channel(None);
    let since = vl_record::now_ns();
    let lab_events = LabEvents::default();
    let lab = LabHandle {
        hub: hub_tx.clone(),
        feedback,
        frames,
        watchers: Arc::default(),
        record: vl_record::Feed::default(),
        events: lab_events.clone(),
        live: vl_host::LiveEvents::default(),
        log: tokio::sync::broadcast::channel(1).0,
        since_ns: since,
        gate: gate.clone(),
        scene: None,
        experiments: config.experiments.experiments().cloned().collect(),
    };
    let front = Front::new(
        config.clone(),
        session.clone(),
        events_tx.clone(),
        lab_events.clone(),
        since,
    );
    let extended = vl_host::run_extensions(config.extensions.clone(), lab.clone());
    tokio::select! {
        () = front.run(hub_rx, events_rx) => {}
        () = accept(listener, lab, config, Admission::with_capacity(CONNECTIONS)) => {}
        () = watch_accounts(gate, hub_tx) => {}
        () = extended => {}
        Err(e) = watch_cells(&session, &zenoh.trust, events_tx) => error!("the gateway no longer sees its cells: {e}"),
    }
}

/// Tells the front which cells come and go, and what each says of itself:
/// on a network of certificates, only the cells its authority issued to
/// (Zenoh's access control keeps others off; this keeps the gateway's
/// own view so too), each speaking of itself only.
async fn watch_cells(
    session: &zenoh::Session,
    trust: &ZenohTrust,
    events: mpsc::Sender<Event>,
) -> Result<(), ZenohError> {
    let tokens = session
        .liveliness()
        .declare_subscriber(keys::CELLS)
        .history(true)
        .await?;
    let infos = session.declare_subscriber(keys::INFOS).await?;
    let member = |name: &CellName| match trust {
        ZenohTrust::Router(router) => router.is_cell(name),
        ZenohTrust::Open | ZenohTrust::Member(_) => true,
    };
    let hush = Hush::default();
    loop {
        let event = tokio::select! {
            token = tokens.recv_async() => {
                let Ok(token) = token else { return Ok(()) };
                let Some(name) = keys::cell_of(token.key_expr().as_str()).filter(member) else {
                    if hush.speak() {
                        warn!("{} is no cell of this gateway's: ignored", token.key_expr());
                    }
                    continue;
                };
                match token.kind() {
                    SampleKind::Put => Event::Up(name),
                    SampleKind::Delete => Event::Gone(name),
                }
            }
            sample = infos.recv_async() => {
                let Ok(sample) = sample else { return Ok(()) };
                if !within(&sample, keys::MOST_TEXT, &hush) {
                    continue;
                }
                let from = keys::cell_of(sample.key_expr().as_str());
                match serde_json::from_slice::<vl_core::CellInfo>(&sample.payload().to_bytes()) {
                    Ok(info) if from.as_ref() == Some(&info.name) && member(&info.name) => Event::Info(info),
                    Ok(info) if hush.speak() => {
                        warn!("{} speaks for cell {}: ignored", sample.key_expr(), info.name);
                        continue;
                    }
                    Err(e) if hush.speak() => {
                        warn!("{} is no cell's info: {e}", sample.key_expr());
                        continue;
                    }
                    _ => continue,
                }
            }
        };
        if events.send(event).await.is_err() {
            return Ok(());
        }
    }
}

/// The name a Guest's path asks for (`/cells/NAME`), if any.
fn asked_cell(path: Option<&str>) -> Option<Result<CellName, String>> {
    let name = path?.strip_prefix("/cells/")?.trim_end_matches('/');
    Some(name.parse().map_err(|_| name.to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_asks_for_a_cell_by_name() {
        assert_eq!(asked_cell(Some("/")), None);
        assert_eq!(asked_cell(None), None);
        assert_eq!(asked_cell(Some("/cells/b")), Some(Ok("b".parse().unwrap())));
        assert_eq!(asked_cell(Some("/cells/B C")), Some(Err("B C".into())));
    }
}
