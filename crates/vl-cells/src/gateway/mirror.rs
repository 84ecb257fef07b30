//! One cell as the gateway holds it: its newest feedback and frame, taken
//! from Zenoh once and watched by every Guest of it, and what it tells its
//! observers, handed to the front to pass on.

use std::time::Duration;

use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;
use tokio_tungstenite::tungstenite::{Bytes, Utf8Bytes};
use tracing::warn;
use vl_core::{CellName, HostMessage, Wire};

use super::event::Event;
use crate::{ZenohError, keys, within};
use vl_host::Hush;
use vl_host::hub::Streams;

/// How long after a cell's last message the gateway asks it again what a
/// late observer is told: a burst of messages costs one asking.
const CATCH_UP_AFTER: Duration = Duration::from_millis(50);
/// How soon a cell that did not answer is asked again.
const ASK_AGAIN: Duration = Duration::from_millis(250);

/// A cell's newest feedback and frame, and the tasks that keep them.
pub(super) struct Mirror {
    name: CellName,
    feedback: watch::Sender<Option<HostMessage>>,
    frames: watch::Sender<Option<Bytes>>,
    tasks: Vec<JoinHandle<()>>,
    /// Taking frames, while a Guest is on the cell: the cell makes them
    /// only while someone takes them.
    taking_frames: Option<JoinHandle<()>>,
}

impl Drop for Mirror {
    fn drop(&mut self) {
        for task in self.tasks.iter().chain(&self.taking_frames) {
            task.abort();
        }
    }
}

impl Mirror {
    /// Starts taking `name`'s feedback and messages from Zenoh.
    pub(super) fn start(
        session: &zenoh::Session,
        name: &CellName,
        events: mpsc::Sender<Event>,
    ) -> Mirror {
        let (feedback, _) = watch::channel(None);
        let (frames, _) = watch::channel(None);
        let tasks = vec![
            tokio::spawn(take_feedback(
                session.clone(),
                name.clone(),
                feedback.clone(),
            )),
            tokio::spawn(take_messages(session.clone(), name.clone(), events)),
        ];
        Mirror {
            name: name.clone(),
            feedback,
            frames,
            tasks,
            taking_frames: None,
        }
    }

    /// Takes the cell's frames while `wanted`, else not.
    pub(super) fn want_frames(&mut self, session: &zenoh::Session, wanted: bool) {
        match (&self.taking_frames, wanted) {
            (None, true) => {
                let task = take_frames(session.clone(), self.name.clone(), self.frames.clone());
                self.taking_frames = Some(tokio::spawn(task));
            }
            (Some(task), false) => {
                task.abort();
                self.taking_frames = None;
                self.frames.send_replace(None);
            }
            _ => {}
        }
    }

    /// What a Guest of this cell streams once welcomed.
    pub(super) fn streams(&self) -> Box<Streams> {
        Box::new(Streams {
            feedback: self.feedback.subscribe(),
            frames: self.frames.subscribe(),
        })
    }
}

async fn take_feedback(
    session: zenoh::Session,
    name: CellName,
    newest: watch::Sender<Option<HostMessage>>,
) {
    let taken = async {
        let samples = session.declare_subscriber(keys::feedback(&name)).await?;
        let hush = Hush::default();
        while let Ok(sample) = samples.recv_async().await {
            if !within(&sample, keys::MOST_TEXT, &hush) {
                continue;
            }
            let bytes = sample.payload().to_bytes();
            match std::str::from_utf8(&bytes).map(HostMessage::decode) {
                Ok(Ok(message @ HostMessage::Feedback(_))) => {
                    newest.send_replace(Some(message));
                }
                _ if hush.speak() => warn!("cell {name} sent feedback that is no feedback message"),
                _ => {}
            }
        }
        Ok::<_, ZenohError>(())
    };
    if let Err(e) = taken.await {
        warn!("the gateway takes no feedback from cell {name}: {e}");
    }
}

async fn take_frames(
    session: zenoh::Session,
    name: CellName,
    newest: watch::Sender<Option<Bytes>>,
) {
    let taken = async {
        let samples = session.declare_subscriber(keys::frames(&name)).await?;
        let hush = Hush::default();
        while let Ok(sample) = samples.recv_async().await {
            if !within(&sample, keys::MOST_FRAME, &hush) {
                continue;
            }
            newest.send_replace(Some(Bytes::from(sample.payload().to_bytes().into_owned())));
        }
        Ok::<_, ZenohError>(())
    };
    if let Err(e) = taken.await {
        warn!("the gateway takes no frames from cell {name}: {e}");
    }
}

/// Hands the front each message the cell tells its observers, and, after
/// each burst of them, what a late observer would now be told.
async fn take_messages(session: zenoh::Session, name: CellName, events: mpsc::Sender<Event>) {
    let taken = async {
        let samples = session.declare_subscriber(keys::messages(&name)).await?;
        let hush = Hush::default();
        let mut asking = Some(tokio::time::Instant::now());
        loop {
            tokio::select! {
                sample = samples.recv_async() => {
                    let Ok(sample) = sample else { return Ok(()) };
                    if !within(&sample, keys::MOST_TEXT, &hush) {
                        continue;
                    }
                    let Ok(text) = Utf8Bytes::try_from(Bytes::from(sample.payload().to_bytes().into_owned())) else {
                        if hush.speak() {
                            warn!("cell {name} told its observers what is no text");
                        }
                        continue;
                    };
                    asking.get_or_insert_with(|| tokio::time::Instant::now() + CATCH_UP_AFTER);
                    if events.send(Event::Told(name.clone(), text)).await.is_err() {
                        return Ok(());
                    }
                }
                () = async { tokio::time::sleep_until(asking.unwrap_or_else(tokio::time::Instant::now)).await }, if asking.is_some() => {
                    asking = None;
                    match catch_up(&session, &name).await? {
                        Some(told) => {
                            if events.send(Event::CaughtUp(name.clone(), told)).await.is_err() {
                                return Ok(());
                            }
                        }
                        // Not answering yet (a cell just up declares its
                        // queryable after its token): ask again.
                        None => asking = Some(tokio::time::Instant::now() + ASK_AGAIN),
                    }
                }
            }
        }
    };
    let result: Result<(), ZenohError> = taken.await;
    if let Err(e) = result {
        warn!("the gateway hears nothing more from cell {name}: {e}");
    }
}

/// What `name` tells a late observer, asked of it over Zenoh: its welcome
/// first, or none.
async fn catch_up(
    session: &zenoh::Session,
    name: &CellName,
) -> Result<Option<Vec<HostMessage>>, ZenohError> {
    let replies = session
        .get(keys::catch_up(name))
        .timeout(Duration::from_secs(2))
        .await?;
    while let Ok(reply) = replies.recv_async().await {
        let Ok(sample) = reply.result() else { continue };
        if !within(sample, keys::MOST_CATCH_UP, &Hush::default()) {
            continue;
        }
        let texts: Vec<String> =
            serde_json::from_slice(&sample.payload().to_bytes()).unwrap_or_default();
        let told: Vec<HostMessage> = texts
            .iter()
            .filter_map(|text| HostMessage::decode(text).ok())
            .collect();
        if matches!(told.first(), Some(HostMessage::Welcome { .. })) {
            return Ok(Some(told));
        }
        warn!("cell {name} answered what a late observer is told without a welcome");
    }
    Ok(None)
}
