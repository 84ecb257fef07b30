//! What an integration plugs into the Host with, instead of the server
//! naming each: its pages on the lab's port, the sessions it opens for the
//! gate, its part of the lab's status, and a task that runs as long as the
//! lab does, hearing the lab's events. The LMS side (`vl-lti`) is one.

use std::future::Future;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use vl_core::HostStatus;

use super::LabHandle;
use super::admission::Ticket;
use super::socket::Socket;
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

    /// The WebSocket protocol it serves on the lab's port, if a client's
    /// upgrade offers it (`offered`: its `Sec-WebSocket-Protocol`).
    fn socket_protocol(&self, offered: &str) -> Option<SocketProtocol> {
        let _ = offered;
        None
    }

    /// Serves one client of its `socket_protocol`, until it leaves.
    fn serve_socket(self: Arc<Self>, socket: Socket, client: SocketClient) -> ExtensionTask {
        let _ = (socket, client);
        Box::pin(async {})
    }

    /// What it runs for as long as the lab does, reaching it by `lab`
    /// (its hub, feeds, events and gate). Called as the lab starts, before
    /// its first connection: what it listens to here, it hears from the
    /// start.
    fn run(self: Arc<Self>, lab: LabHandle) -> ExtensionTask {
        let _ = lab;
        Box::pin(std::future::pending())
    }
}

/// A WebSocket protocol an extension serves on the lab's port, told apart
/// from a Guest's by its subprotocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SocketProtocol {
    /// The subprotocol the upgrade is answered with.
    pub name: &'static str,
    /// The largest message its clients may send.
    pub max_message: usize,
}

/// One client of an extension's WebSocket protocol: its connection, the
/// slot admission gave it (which says when it is pushed out), and the lab.
pub struct SocketClient {
    pub id: u64,
    pub peer: SocketAddr,
    pub ticket: Ticket,
    pub lab: LabHandle,
    /// A client that answers no ping for this long is let go.
    pub ping_timeout: Duration,
}

/// The extensions of a lab, run together. Each `run` is called now,
/// before the lab takes its first connection or its hub says anything,
/// so what an extension listens to it hears from the start.
pub fn run_all(
    extensions: Vec<Arc<dyn Extension>>,
    lab: LabHandle,
) -> impl Future<Output = ()> + Send {
    let tasks: Vec<ExtensionTask> = extensions.into_iter().map(|e| e.run(lab.clone())).collect();
    async move {
        futures_util::future::join_all(tasks).await;
        // None left running (or none at all): the lab runs on.
        std::future::pending().await
    }
}
