//! What an integration plugs into the Host with, instead of the server
//! naming each: its pages on the lab's port, the sessions it opens for the
//! gate, its part of the lab's status, and a task that runs as long as the
//! lab does, hearing the lab's events. The LMS side (`vl-lti`) is one.

use std::future::Future;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::Arc;

use vl_core::HostStatus;

use super::events::LabEvents;
use crate::accounts::gate::SessionCheck;

/// A task that runs for as long as the lab does.
pub type ExtensionTask = Pin<Box<dyn Future<Output = ()> + Send>>;

/// An integration the Host (or a gateway) runs beside its lab.
pub trait Extension: Send + Sync + std::fmt::Debug {
    /// Its pages on the lab's port, for a request from `address`.
    fn routes(self: Arc<Self>, address: IpAddr) -> axum::Router {
        let _ = address;
        axum::Router::new()
    }

    /// The sessions it opens, for the gate to let in whom they vouch for.
    fn sessions(&self) -> Option<Arc<dyn SessionCheck>> {
        None
    }

    /// Its part of the lab's status.
    fn status(&self, status: &mut HostStatus) {
        let _ = status;
    }

    /// What it runs for as long as the lab does, hearing `events`.
    fn run(self: Arc<Self>, events: LabEvents) -> ExtensionTask {
        let _ = events;
        Box::pin(std::future::pending())
    }
}

/// The extensions of a lab, run together.
pub(crate) async fn run_all(extensions: Vec<Arc<dyn Extension>>, events: LabEvents) {
    let tasks = extensions.into_iter().map(|e| e.run(events.clone()));
    futures_util::future::join_all(tasks).await;
    // None left running (or none at all): the lab runs on.
    std::future::pending().await
}
