//! A cell's side: joins the gateway, says it is up, publishes what its
//! watchers see once, and takes the gateway's Guests as its hub's clients.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::{broadcast, mpsc, oneshot};
use tokio_tungstenite::tungstenite::Message;
use tracing::{debug, info, warn};
use vl_core::{CellInfo, CellName, ExperimentId, PROTOCOL_VERSION, Role, Wire};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::SampleKind;

use super::link::{LinkDown, LinkUp};
use super::{CellOptions, ZenohError, keys, within};
use vl_host::Admitted;
use vl_host::Hush;
use vl_host::LabEvent;
use vl_host::LabHandle;
use vl_host::Watching;
use vl_host::hub::{OUTBOX, Status, ToConnection, ToHub};

/// How often a cell tells the gateway how it is.
const INFO_EVERY: Duration = Duration::from_millis(500);
/// The cell's own clients for the gateway are numbered from here, apart
/// from the connections it accepts itself.
const FIRST_ID: u64 = 1 << 48;
/// Links a cell holds at once: as many Guests as a gateway serves.
const MOST_LINKS: usize = 4096;

/// A cell's side of its Host: the lab, and what it offers.
struct Cell {
    lab: LabHandle,
    experiments: Vec<ExperimentId>,
}

/// Joins the gateway of `options` and serves it for as long as the Host
/// runs (never returning: a cell that cannot join still serves alone).
pub(crate) async fn join(options: CellOptions, lab: LabHandle) {
    let experiments = lab.experiments.iter().map(|e| e.id.clone()).collect();
    let cell = Cell { lab, experiments };
    let name = options.name.clone();
    let session = match super::open(&options.zenoh).await {
        Ok(session) => session,
        Err(e) => {
            warn!("cell {name} cannot join its gateway: {e}");
            return std::future::pending().await;
        }
    };
    if let Err(e) = serve(&session, &name, cell).await {
        warn!("cell {name} no longer serves its gateway: {e}");
    }
    std::future::pending().await
}

async fn serve(session: &zenoh::Session, name: &CellName, cell: Cell) -> Result<(), ZenohError> {
    let _token = session.liveliness().declare_token(keys::cell(name)).await?;
    info!("cell {name} is up at its gateway");
    let ids = Arc::new(std::sync::atomic::AtomicU64::new(FIRST_ID));
    tokio::try_join!(
        watched(session, name, &cell, ids.clone()),
        tell_info(session, name, &cell),
        catch_ups(session, name, &cell.lab.hub),
        links(session, name, &cell, ids),
    )?;
    Ok(())
}

/// One observer of the cell's own, for every watcher at the gateway: what
/// it is told, and the newest feedback and frames, published once.
async fn watched(
    session: &zenoh::Session,
    name: &CellName,
    cell: &Cell,
    ids: Arc<std::sync::atomic::AtomicU64>,
) -> Result<(), ZenohError> {
    let messages = session
        .declare_publisher(keys::messages(name))
        .congestion_control(CongestionControl::Block)
        .await?;
    let feedback_out = session
        .declare_publisher(keys::feedback(name))
        .priority(Priority::InteractiveHigh)
        .express(true)
        .await?;
    let frames_out = session.declare_publisher(keys::frames(name)).await?;
    // Frames are made only while someone watches: the gateway takes them
    // only while one of its Guests is on this cell.
    let looked_at = frames_out.matching_listener().await?;
    let (mut feedback, mut frames) = (cell.lab.feedback.clone(), cell.lab.frames.clone());
    let mut watching = None;
    loop {
        let id = ids.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let (to_me, mut inbox) = mpsc::channel(OUTBOX);
        let hello = ToHub::Hello {
            id,
            admitted: Admitted::anyone(),
            protocol: PROTOCOL_VERSION,
            role: Role::Observer,
            resume: None,
        };
        if cell
            .lab
            .hub
            .send(ToHub::Join(id, to_me, None))
            .await
            .is_err()
            || cell.lab.hub.send(hello).await.is_err()
        {
            return Ok(());
        }
        let mut welcomed = false;
        loop {
            tokio::select! {
                out = inbox.recv() => match out {
                    Some(ToConnection::Send(message)) => {
                        messages.put(message.into_data().to_vec()).await?;
                    }
                    Some(ToConnection::Subscribe | ToConnection::Watch(_)) => {
                        welcomed = true;
                        feedback.mark_changed();
                        frames.mark_changed();
                    }
                    // Let go (it fell behind): join again.
                    Some(ToConnection::End(..)) | None => break,
                },
                status = looked_at.recv_async() => {
                    let Ok(status) = status else { return Ok(()) };
                    watching = status.matching().then(|| Watching::new(&cell.lab.watchers));
                }
                Ok(()) = feedback.changed(), if welcomed => {
                    let latest = feedback.borrow_and_update().clone();
                    if let Some(message) = latest {
                        feedback_out.put(message.encode()).await?;
                    }
                }
                Ok(()) = frames.changed(), if welcomed && watching.is_some() => {
                    let latest = frames.borrow_and_update().clone();
                    if let Some(frame) = latest {
                        frames_out.put(frame.to_vec()).await?;
                    }
                }
            }
        }
        debug!("cell {name}: its watchers' observer joins again");
        let _ = cell.lab.hub.send(ToHub::Leave(id, false)).await;
    }
}

/// Tells the gateway how the cell is, twice a second.
async fn tell_info(
    session: &zenoh::Session,
    name: &CellName,
    cell: &Cell,
) -> Result<(), ZenohError> {
    let out = session.declare_publisher(keys::info(name)).await?;
    let mut every = tokio::time::interval(INFO_EVERY);
    loop {
        every.tick().await;
        let (tx, rx) = oneshot::channel();
        if cell.lab.hub.send(ToHub::Status(tx)).await.is_err() {
            return Ok(());
        }
        let Ok(Status::Host(status)) = rx.await else {
            return Ok(());
        };
        let info = CellInfo {
            name: name.clone(),
            experiments: cell.experiments.clone(),
            mounted: status.mounted,
            lab: status.lab,
            run: status.run,
            operator: status.operator,
            line: status.queue.len() as u32,
        };
        out.put(serde_json::to_vec(&info).unwrap_or_default())
            .await?;
    }
}

/// Answers the gateway's asking what a late observer is told.
async fn catch_ups(
    session: &zenoh::Session,
    name: &CellName,
    hub: &mpsc::Sender<ToHub>,
) -> Result<(), ZenohError> {
    let queries = session.declare_queryable(keys::catch_up(name)).await?;
    while let Ok(query) = queries.recv_async().await {
        let (tx, rx) = oneshot::channel();
        if hub.send(ToHub::CatchUp(tx)).await.is_err() {
            return Ok(());
        }
        let Ok(told) = rx.await else { return Ok(()) };
        let texts: Vec<String> = told.iter().map(Wire::encode).collect();
        let body = serde_json::to_vec(&texts).unwrap_or_default();
        query.reply(query.key_expr().clone(), body).await?;
    }
    Ok(())
}

/// The gateway's Guests at this cell, each one of the hub's clients.
async fn links(
    session: &zenoh::Session,
    name: &CellName,
    cell: &Cell,
    ids: Arc<std::sync::atomic::AtomicU64>,
) -> Result<(), ZenohError> {
    let hub = &cell.lab.hub;
    let ups = session.declare_subscriber(keys::ups(name)).await?;
    let tokens = session
        .liveliness()
        .declare_subscriber(keys::links(name))
        .await?;
    let mut open: HashMap<String, (u64, tokio::task::JoinHandle<()>)> = HashMap::new();
    let hush = Hush::default();
    loop {
        tokio::select! {
            sample = ups.recv_async() => {
                let Ok(sample) = sample else { return Ok(()) };
                let Some(link) = keys::link_of(sample.key_expr().as_str()).map(str::to_owned) else {
                    continue;
                };
                if !within(&sample, keys::MOST_TEXT, &hush) {
                    continue;
                }
                let up: LinkUp = match serde_json::from_slice(&sample.payload().to_bytes()) {
                    Ok(up) => up,
                    Err(e) => {
                        if hush.speak() {
                            warn!("cell {name}: link {link} sent what is no link message: {e}");
                        }
                        continue;
                    }
                };
                let to_hub = match up {
                    LinkUp::Hello { admitted, protocol, role, resume } => {
                        let id = match open.get(&link) {
                            Some((id, _)) => *id,
                            None if open.len() >= MOST_LINKS => {
                                if hush.speak() {
                                    warn!("cell {name}: {MOST_LINKS} links open, link {link} refused");
                                }
                                continue;
                            }
                            None => {
                                let id = ids.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                                let (to_me, inbox) = mpsc::channel(OUTBOX);
                                if hub.send(ToHub::Join(id, to_me, None)).await.is_err() {
                                    return Ok(());
                                }
                                let down = session.declare_publisher(keys::down(name, &link)).await?;
                                let relay = relay_down(inbox, down, id, cell.lab.events.listen());
                                open.insert(link.clone(), (id, tokio::spawn(relay)));
                                id
                            }
                        };
                        ToHub::Hello { id, admitted, protocol, role, resume }
                    }
                    LinkUp::Message { message } => match open.get(&link) {
                        Some((id, _)) => ToHub::Message(*id, message),
                        None => continue,
                    },
                    LinkUp::Leave { meant } => match open.remove(&link) {
                        Some((id, _)) => ToHub::Leave(id, meant),
                        None => continue,
                    },
                };
                if hub.send(to_hub).await.is_err() {
                    return Ok(());
                }
            }
            token = tokens.recv_async() => {
                let Ok(token) = token else { return Ok(()) };
                // The gateway let go of the Guest, or the gateway is gone.
                if token.kind() == SampleKind::Delete
                    && let Some(link) = keys::link_of(token.key_expr().as_str())
                    && let Some((id, _)) = open.remove(link)
                    && hub.send(ToHub::Leave(id, false)).await.is_err()
                {
                    return Ok(());
                }
            }
        }
    }
}

/// What the hub tells a link's client `id`, down to the gateway, and the
/// end of each run it drove.
async fn relay_down(
    mut inbox: mpsc::Receiver<ToConnection>,
    down: zenoh::pubsub::Publisher<'static>,
    id: u64,
    mut events: broadcast::Receiver<LabEvent>,
) {
    loop {
        let out = tokio::select! {
            out = inbox.recv() => match out {
                Some(out) => out,
                None => return,
            },
            event = events.recv() => {
                let ended = match event {
                    Ok(LabEvent::RunEnded(ended)) => ended,
                    Err(broadcast::error::RecvError::Lagged(_)) => continue,
                    Err(broadcast::error::RecvError::Closed) => return,
                };
                if ended.driver.as_ref().is_some_and(|d| d.connection == id) {
                    let said = LinkDown::RunEnded { summary: Box::new(ended.summary.clone()) };
                    if down.put(said.encode()).await.is_err() {
                        return;
                    }
                }
                continue;
            }
        };
        let (said, last) = match out {
            ToConnection::Send(message) => match message {
                Message::Text(text) => (
                    LinkDown::Send {
                        text: text.to_string(),
                    },
                    false,
                ),
                _ => continue,
            },
            ToConnection::Subscribe | ToConnection::Watch(_) => (LinkDown::Welcomed, false),
            ToConnection::End(code, why) => (LinkDown::End { code, why }, true),
        };
        if down.put(said.encode()).await.is_err() || last {
            return;
        }
    }
}
