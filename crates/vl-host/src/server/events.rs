//! What happens in the lab that its integrations act on, told on one
//! broadcast instead of the hub calling each: a run's end, with who drove
//! it and how they came in (the LMS grades it for the launch whose session
//! drove it; a cell tells its gateway, which grades as the Guest it let in).

use std::sync::Arc;

use tokio::sync::broadcast;
use vl_core::{HostMessage, Summary};

use crate::accounts::gate::Admitted;

/// Events kept for the slowest listener; one further behind misses the
/// oldest. Runs end seconds apart at the most: 64 is a minute of slack.
const EVENTS_KEPT: usize = 64;

/// Something that happened in the lab.
#[derive(Debug, Clone)]
pub enum LabEvent {
    /// A run ended.
    RunEnded(Arc<RunEnded>),
}

/// A run's end: its number at this lab, who drove it, and its summary as
/// every Guest was told it.
#[derive(Debug)]
pub struct RunEnded {
    /// Its number at this lab; none for a run at a gateway's cell, which
    /// numbers its own.
    pub run: Option<u64>,
    /// None for a run no one drove to its end as operator (the lab's own
    /// drive back to the start pose is never told).
    pub driver: Option<RunDriver>,
    pub summary: Summary,
}

/// Who drove a run: their connection to the hub and what the gate made
/// of their hello.
#[derive(Debug, Clone)]
pub struct RunDriver {
    pub connection: u64,
    pub admitted: Admitted,
}

/// What the lab's live views (Foxglove's) are made of besides its feeds:
/// each message the hub tells every client, and each round trip a
/// connection measures.
#[derive(Debug, Clone)]
pub enum LiveEvent {
    Told(Arc<HostMessage>),
    RoundTrip { connection: u64, ms: f64 },
}

/// Live events kept for the slowest listener, which skips the oldest.
const LIVE_KEPT: usize = 256;

/// The lab's live events: made only while someone listens, so a lab with
/// no live views pays nothing for them.
#[derive(Debug, Clone)]
pub struct LiveEvents(broadcast::Sender<LiveEvent>);

impl Default for LiveEvents {
    fn default() -> Self {
        LiveEvents(broadcast::channel(LIVE_KEPT).0)
    }
}

impl LiveEvents {
    /// Tells the event `made` makes, if anyone listens.
    pub fn tell(&self, made: impl FnOnce() -> LiveEvent) {
        if self.0.receiver_count() > 0 {
            let _ = self.0.send(made());
        }
    }

    /// The events from now on.
    pub fn listen(&self) -> broadcast::Receiver<LiveEvent> {
        self.0.subscribe()
    }
}

/// The lab's events, for anyone to listen to.
#[derive(Debug, Clone)]
pub struct LabEvents(broadcast::Sender<LabEvent>);

impl Default for LabEvents {
    fn default() -> Self {
        LabEvents(broadcast::channel(EVENTS_KEPT).0)
    }
}

impl LabEvents {
    /// Tells `event` to everyone listening now (no one may be).
    pub fn tell(&self, event: LabEvent) {
        let _ = self.0.send(event);
    }

    /// The events from now on.
    pub fn listen(&self) -> broadcast::Receiver<LabEvent> {
        self.0.subscribe()
    }
}
