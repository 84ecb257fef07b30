//! The Foxglove views of the lab, made once for every Foxglove client: one
//! task per Host turns each feedback, frame, broadcast and log line into
//! its views (`vl_record::Views`, as the recorder does) and hands the same
//! encoded bytes to every client, keeping the newest of each latched
//! channel (`Topic::latched`) for those who subscribe later.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use bytes::Bytes;
use tokio::sync::{broadcast, watch};
use vl_core::{HostMessage, LabScene};
use vl_host::LiveEvent;
use vl_record::{Level, Topic, View, Views, now_ns};

/// Views waiting for the slowest client: past this it skips to the newest.
const FANOUT: usize = 512;

/// What every Foxglove client shares.
#[derive(Clone)]
pub(crate) struct LiveFeed {
    views: broadcast::Sender<Arc<View>>,
    latched: Arc<Mutex<HashMap<Topic, Vec<Arc<View>>>>>,
    /// Clients subscribed to the camera or its annotations: frames are
    /// made into base64 JSON only for them.
    camera: Arc<AtomicUsize>,
}

/// What the feed is made from.
pub(crate) struct Sources {
    pub scene: LabScene,
    pub since_ns: u64,
    pub feedback: watch::Receiver<Option<HostMessage>>,
    pub frames: watch::Receiver<Option<Bytes>>,
    pub log: broadcast::Sender<(Level, String)>,
    /// What the hub tells everyone, and the round trips measured.
    pub live: broadcast::Receiver<LiveEvent>,
}

impl LiveFeed {
    /// The feed, and the task that makes the views.
    pub(crate) fn start(sources: Sources) -> (LiveFeed, impl std::future::Future<Output = ()>) {
        let feed = LiveFeed {
            views: broadcast::channel(FANOUT).0,
            latched: Arc::default(),
            camera: Arc::default(),
        };
        let task = feed.clone().run(sources);
        (feed, task)
    }

    pub(super) fn subscribe(&self) -> broadcast::Receiver<Arc<View>> {
        self.views.subscribe()
    }

    /// The newest messages of latched channel `topic`.
    pub(super) fn latched(&self, topic: Topic) -> Vec<Arc<View>> {
        let latched = self.latched.lock().unwrap_or_else(|e| e.into_inner());
        latched.get(&topic).cloned().unwrap_or_default()
    }

    /// A client starts (`true`) or stops watching the camera.
    pub(super) fn watch_camera(&self, watching: bool) {
        if watching {
            self.camera.fetch_add(1, Ordering::Relaxed);
        } else {
            self.camera.fetch_sub(1, Ordering::Relaxed);
        }
    }

    /// A Guest's round trip, as the Host's pings measured it.
    fn round_trip(&self, connection: u64, ms: f64) {
        if self.watched() {
            let round_trip = vl_record::RoundTrip { connection, ms };
            self.publish(vec![View::round_trip(now_ns(), round_trip)]);
        }
    }

    /// Whether any Foxglove client is connected.
    fn watched(&self) -> bool {
        self.views.receiver_count() > 0
    }

    fn publish(&self, views: Vec<View>) {
        let mut fresh: HashMap<Topic, Vec<Arc<View>>> = HashMap::new();
        for view in views {
            let view = Arc::new(view);
            if view.topic.latched() {
                fresh.entry(view.topic).or_default().push(view.clone());
            }
            // Nobody listening is no error.
            let _ = self.views.send(view);
        }
        if !fresh.is_empty() {
            let mut latched = self.latched.lock().unwrap_or_else(|e| e.into_inner());
            latched.extend(fresh);
        }
    }

    async fn run(self, mut sources: Sources) {
        let mut views = Views::new(sources.since_ns, Some(sources.scene), Default::default());
        self.publish(views.lab(now_ns()));
        let mut log = sources.log.subscribe();
        loop {
            tokio::select! {
                event = sources.live.recv() => match event {
                    Ok(LiveEvent::Told(message)) => self.publish(views.sent(now_ns(), &message)),
                    Ok(LiveEvent::RoundTrip { connection, ms }) => self.round_trip(connection, ms),
                    // Fallen behind: a view is lost, not the lab's pace.
                    Err(broadcast::error::RecvError::Lagged(_)) => {}
                    Err(broadcast::error::RecvError::Closed) => return,
                },
                // Feedback and the log change often and latch nothing:
                // made into views only while a client is there to take them.
                Ok(()) = sources.feedback.changed() => {
                    let latest = sources.feedback.borrow_and_update().clone();
                    if let Some(message) = latest
                        && self.watched()
                    {
                        self.publish(views.sent(now_ns(), &message));
                    }
                }
                Ok(()) = sources.frames.changed() => {
                    let latest = sources.frames.borrow_and_update().clone();
                    if let Some(frame) = latest
                        && self.camera.load(Ordering::Relaxed) > 0
                    {
                        self.publish(views.frame(&frame));
                    }
                }
                line = log.recv() => match line {
                    Ok(_) if !self.watched() => {}
                    Ok((level, line)) => self.publish(vec![View::log(now_ns(), level, &line)]),
                    Err(broadcast::error::RecvError::Lagged(skipped)) => {
                        let line = format!("{skipped} lines of the Host's log skipped");
                        self.publish(vec![View::log(now_ns(), Level::Warning, &line)]);
                    }
                    Err(broadcast::error::RecvError::Closed) => return,
                },
            }
        }
    }
}
