//! The Host's side of the Media: a WebSocket server speaking protocol v1.
//!
//! One task per connection reads and writes its socket (`connection`); one
//! hub task owns the session — who is operator, the supervisor net, the
//! current definition — and is the only place that changes it, so there
//! are no locks around session state (`hub`). Feedback and frames bypass
//! the hub: every connection watches the lab's newest values directly.
//!
//! Everything a client can make the Host hold is bounded (`admission`
//! caps connections and evicts the oldest that never said hello; queues
//! are bounded; messages are limited in size and rate), and every stage
//! has a timeout, so no client, however careless or hostile, can slow the
//! operator's loop or lock anyone out.

pub(crate) mod admission;
pub(crate) mod bench;
pub(crate) mod bucket;
mod busy;
mod connection;
pub(crate) mod events;
pub(crate) mod extension;
mod http;
pub(crate) mod hub;
pub(crate) mod origin;
pub(crate) mod pacing;
pub mod socket;
pub mod web;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::TcpListener;
use tokio::sync::mpsc;
use tracing::{debug, error, warn};
use vl_core::{AccessNet, Experiment, Experiments, Supervisor, SupervisorError};

use crate::accounts::audit::Audit;
use crate::accounts::gate::{Gate, Observers};
use crate::accounts::users::Users;
use crate::lab::{FramePolicy, Lab};
use crate::tls::Tls;
pub use admission::Admission;
use connection::ConnectionTask;
use hub::Hub;
pub use hub::{ForecastSettings, MOST_FORECAST_SEEDS};

/// How the Host admits people and how long it waits for them.
#[derive(Debug, Clone)]
pub struct HostConfig {
    /// When set, an operator's `hello` must carry this token (or log in).
    pub token: Option<String>,
    /// The lab's accounts: with them, operators log in.
    pub users: Option<Users>,
    /// With accounts, whether anyone may watch or only people with one.
    pub observers: Observers,
    /// Where who did what is logged (none: nowhere).
    pub audit: Audit,
    /// WebSocket over TLS only (`wss://`), with this certificate.
    pub tls: Option<Tls>,
    /// What the lab offers, in the order Guests list it, each designed
    /// and verified.
    pub experiments: Experiments,
    /// An operator who sends no command for this long during a run loses
    /// the run and the role.
    pub lease: Duration,
    /// How long the operator drives while others wait for control; none:
    /// until they leave.
    pub slot: Option<Duration>,
    /// A client that answers none of the Host's pings for this long is
    /// disconnected (a frozen or vanished Guest).
    pub ping_timeout: Duration,
    /// A client that has not said hello this long after connecting is
    /// disconnected.
    pub hello_timeout: Duration,
    /// Which camera frames are sent.
    pub frames: FramePolicy,
    /// Web pages from these origins may open a WebSocket, besides the
    /// Host's own.
    pub allow_origins: origin::AllowedOrigins,
    /// How long an operator whose link dropped keeps the role and the run
    /// (the robot held still meanwhile), to say hello again with `resume`.
    pub grace: Duration,
    /// Where the labs' and the access design's controlled nets are
    /// (`<dir>/<lab>/controlled.pnml`, `<dir>/access/controlled.pnml`, as
    /// `vl lab nets --out dir` writes them); the shipped ones if none.
    pub nets: Option<PathBuf>,
    /// Drive the robot back to the lab's start pose after every run.
    pub reset: bool,
    /// Fold each camera sighting into the pose estimate at its frame's
    /// exposure rather than its arrival (off only to measure what that is
    /// worth).
    pub compensate_latency: bool,
    /// What a navigation definition's forecast must show for a run to start.
    pub forecast: ForecastSettings,
    /// Where every run is recorded; none: nowhere.
    pub recordings: Option<vl_record::Catalogue>,
    /// What plugs into the lab: a gateway it joins as a cell, ROS 2, an
    /// LMS's launches and grades, …
    pub extensions: Vec<Arc<dyn extension::Extension>>,
}

impl HostConfig {
    /// The supervisor of the labs offered, from their controlled nets,
    /// with the access net beside them.
    pub fn supervisor(&self) -> Result<Supervisor, SupervisorError> {
        Ok(match &self.nets {
            Some(dir) => {
                Supervisor::load(dir, &self.experiments.ids())?.with_access(AccessNet::load(dir)?)
            }
            None => Supervisor::new(self.experiments.nets())?.with_access(AccessNet::new()?),
        })
    }
}

impl Default for HostConfig {
    fn default() -> Self {
        HostConfig {
            token: None,
            users: None,
            observers: Observers::default(),
            audit: Audit::default(),
            tls: None,
            experiments: Experiments::shipped().clone(),
            lease: Duration::from_secs(30),
            slot: None,
            ping_timeout: Duration::from_secs(10),
            hello_timeout: Duration::from_secs(10),
            frames: FramePolicy::EveryFrame,
            allow_origins: origin::AllowedOrigins::default(),
            grace: Duration::from_secs(10),
            nets: None,
            reset: true,
            compensate_latency: true,
            forecast: ForecastSettings::default(),
            recordings: None,
            extensions: Vec::new(),
        }
    }
}

/// Messages waiting for the hub, from every connection together.
pub const HUB_QUEUE: usize = 256;

/// Accepts connections on `listener` and serves the lab until the task is dropped.
pub(crate) async fn serve(listener: TcpListener, lab: Lab, config: HostConfig) {
    let (hub_tx, hub_rx) = mpsc::channel(HUB_QUEUE);
    let events = events::LabEvents::default();
    let live = events::LiveEvents::default();
    let config = Arc::new(config);
    let supervisor = match config.supervisor() {
        Ok(supervisor) => supervisor,
        Err(e) => {
            error!("cannot supervise the lab: {e}");
            return;
        }
    };
    let gate = Arc::new(gate_of(&config));
    let handle = LabHandle {
        hub: hub_tx.clone(),
        feedback: lab.feedback.clone(),
        frames: lab.frames.clone(),
        watchers: lab.watchers.clone(),
        record: lab.record.clone(),
        events: events.clone(),
        live: live.clone(),
        log: lab.log.clone(),
        since_ns: lab.since_ns,
        gate: gate.clone(),
        scene: Some(vl_core::LabScene {
            arena: lab.info.arena.clone(),
            robot: lab.info.robot.clone(),
            camera: lab.info.camera,
        }),
        experiments: config.experiments.experiments().cloned().collect(),
    };
    let extended = extension::run_all(config.extensions.clone(), handle.clone());
    let hub = Hub::new(lab, config.clone(), supervisor, events).with_live(live);
    let accounts = watch_accounts(gate, hub_tx);
    // The hub lives exactly as long as the server: dropping this future
    // drops the lab, which stops the robot.
    tokio::select! {
        () = hub.run(hub_rx) => {}
        () = accept(listener, handle, config, Admission::new()) => {}
        () = accounts => {}
        () = extended => {}
    }
}

/// The gate `config` asks for: its accounts, token and observers, and
/// the sessions its extensions open.
pub fn gate_of(config: &HostConfig) -> Gate {
    let gate = Gate::new(
        config.users.clone(),
        config.token.clone(),
        config.observers,
        config.audit.clone(),
    );
    config
        .extensions
        .iter()
        .filter_map(|e| e.sessions())
        .fold(gate, Gate::with_sessions)
}

/// How often the accounts file is looked at while the lab runs.
const ACCOUNTS_CHECK: Duration = Duration::from_secs(1);

/// Reads the accounts file again when it changes, and tells the hub: an
/// account removed on the running lab (`vl users remove`) loses its
/// connections within a second, not at its next hello.
pub async fn watch_accounts(gate: Arc<Gate>, hub: mpsc::Sender<hub::ToHub>) {
    if !gate.has_accounts() {
        return std::future::pending().await;
    }
    let mut check = tokio::time::interval(ACCOUNTS_CHECK);
    loop {
        check.tick().await;
        if let Some(users) = gate.reread()
            && hub.send(hub::ToHub::Accounts(users)).await.is_err()
        {
            return;
        }
    }
}

/// How every part of the server reaches the lab: its hub, and what each
/// client takes from the lab directly, not through the hub — the newest
/// feedback and frames, the count of those watching, the run's recording
/// — the lab's events, its gate and what it is. One handle for a Host's
/// connections (and a gateway's, whose lab is its cells) and every
/// extension (a cell's side, the ROS 2 bridge).
#[derive(Clone)]
pub struct LabHandle {
    pub hub: mpsc::Sender<hub::ToHub>,
    pub feedback: tokio::sync::watch::Receiver<Option<vl_core::HostMessage>>,
    pub frames: tokio::sync::watch::Receiver<Option<bytes::Bytes>>,
    /// Welcomed clients watching the frames (`Watching` counts one).
    pub watchers: Arc<std::sync::atomic::AtomicUsize>,
    pub record: vl_record::Feed,
    pub events: events::LabEvents,
    /// What the hub tells everyone and the round trips measured, for live
    /// views.
    pub live: events::LiveEvents,
    /// The lab's log as it is written (firings, refusals, faults).
    pub log: tokio::sync::broadcast::Sender<(vl_record::Level, String)>,
    /// When the lab's session started, ns since the epoch: its clients'
    /// names and its views' clock.
    pub since_ns: u64,
    /// Who is let in, by accounts, token and extensions' sessions.
    pub gate: Arc<Gate>,
    /// The arena, robot and camera; none at a gateway, whose labs are its
    /// cells.
    pub scene: Option<vl_core::LabScene>,
    /// What the lab offers, in the order Guests list it.
    pub experiments: Arc<[Experiment]>,
}

/// Accepts connections on `listener`, each a task of its own speaking to
/// `lab`'s hub (a Host's, or a gateway's, whose lab is its cells).
pub async fn accept(
    listener: TcpListener,
    lab: LabHandle,
    config: Arc<HostConfig>,
    admission: Admission,
) {
    let mut next_id = 1u64;
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            Err(e) => {
                // Out of file descriptors, most likely: wait for some to close.
                warn!("accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let id = next_id;
        next_id += 1;
        let Some(ticket) = admission.admit(id, peer.ip()) else {
            debug!(%peer, "refused: the Host holds as many connections as it serves");
            busy::refuse(stream, config.tls.as_ref().map(|tls| tls.config.clone()));
            continue;
        };
        let connection = ConnectionTask {
            id,
            lab: lab.clone(),
            config: config.clone(),
            peer,
            ticket,
            identity: None,
        };
        tokio::spawn(async move {
            if let Err(e) = connection.run(stream).await {
                debug!(%peer, "connection {id} ended: {e}");
            }
            crate::memory::give_back();
        });
    }
}
