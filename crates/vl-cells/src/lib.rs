//! Many lab cells behind one gateway, on Zenoh.
//!
//! A cell is a `vl host` that joins a gateway (`cell`): it announces
//! itself with a liveliness token, publishes once what its watchers see
//! (the messages it tells every observer, the newest feedback, camera
//! frames) and takes the Guests the gateway routes to it as links. The
//! gateway (`gateway`) is the lab's one public address: it serves pages,
//! Guests and the line as a Host does, gives each operator a free cell and
//! serves every watcher of a cell from that cell's one copy.
//!
//! The key expressions (`keys`) and the links' messages (`link`) are the
//! whole of what the two say to each other: docs/protocol.md lists them.
//!
//! The network takes only the certificates the gateway's authority issued,
//! each member its own keys (`trust`). A cell is an extension of its Host
//! (`CellSide`, given the lab's `LabHandle`); a gateway runs a Host's
//! connections over its front in place of a hub. The Zenoh session and
//! endpoints here are the ones the lab's ROS 2 side (`vl-ros2`) shares.

mod cell;
mod gateway;
pub(crate) mod keys;
mod link;
mod trust;

pub use trust::{RouterTrust, TrustError, ZenohAuthority, ZenohCredentials, ZenohMember};

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use vl_host::{Extension, ExtensionTask, HostConfig, HostError, LabHandle};

/// A Host's side as one of a gateway's cells: joins the gateway and
/// serves it for as long as the lab runs (a cell that cannot join still
/// serves alone).
#[derive(Debug)]
pub struct CellSide(pub CellOptions);

impl Extension for CellSide {
    fn run(self: Arc<Self>, lab: LabHandle) -> ExtensionTask {
        Box::pin(cell::join(self.0.clone(), lab))
    }
}

/// A gateway, bound and serving Guests in front of the cells that join it.
pub struct Gateway {
    pub addr: SocketAddr,
    task: tokio::task::JoinHandle<()>,
}

impl Gateway {
    /// Binds `listen` for Guests and meets cells on Zenoh by `zenoh`;
    /// `config` is a Host's: accounts, TLS, timeouts (its lab's own fields
    /// are the cells').
    pub async fn start(
        listen: SocketAddr,
        config: HostConfig,
        zenoh: ZenohOptions,
    ) -> Result<Gateway, HostError> {
        let (listener, addr) = vl_host::bind(listen).await?;
        let task = tokio::spawn(gateway::serve(listener, config, zenoh));
        Ok(Gateway { addr, task })
    }

    /// Serves until the process ends (or Zenoh cannot open).
    pub async fn wait(mut self) {
        let _ = (&mut self.task).await;
    }
}

impl Drop for Gateway {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// A Zenoh endpoint on the lab's network: `tcp/HOST:PORT`, or
/// `quic/HOST:PORT` where every peer shows a certificate.
///
/// Certificates go over QUIC, not Zenoh's `tls/` link: that link reads and
/// writes one TLS stream from two tasks at once (eclipse-zenoh/zenoh#2557),
/// and under load a write then fails ("handshake not complete") and the
/// link closes — measured here as a cell lost in most 8-cell, 300-watcher
/// bench runs. QUIC's streams are separate objects over one locked
/// connection, with the same certificates and the same access control.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoint(String);

/// The scheme of an endpoint where every peer shows a certificate.
const SECURED: &str = "quic/";

impl Endpoint {
    /// `tcp/HOST:PORT`, or `quic/HOST:PORT` where `secured`, `host` written
    /// as a URL would.
    pub fn new(secured: bool, host: std::net::IpAddr, port: u16) -> Endpoint {
        let scheme = if secured { SECURED } else { "tcp/" };
        Endpoint(format!("{scheme}{}", std::net::SocketAddr::new(host, port)))
    }

    fn is_secured(&self) -> bool {
        self.0.starts_with(SECURED)
    }

    /// As Zenoh's configuration takes it: QUIC on one stream. With a
    /// stream per priority, a sample can overtake the declaration it
    /// names and is dropped ("Route data with unknown scope": a link's
    /// hello never reached its cell).
    fn for_zenoh(&self) -> String {
        if self.is_secured() {
            format!("{}?multistream=0", self.0)
        } else {
            self.0.clone()
        }
    }

    /// The host part: a name or an address (without an IPv6 one's brackets).
    pub fn host(&self) -> &str {
        let address = self.0.split_once('/').map_or("", |(_, address)| address);
        let host = address.rsplit_once(':').map_or(address, |(host, _)| host);
        host.trim_start_matches('[').trim_end_matches(']')
    }

    /// Whether only this machine can reach it.
    pub fn is_loopback(&self) -> bool {
        let host = self.host();
        host == "localhost"
            || host
                .parse::<std::net::IpAddr>()
                .is_ok_and(|ip| ip.is_loopback())
    }
}

impl std::str::FromStr for Endpoint {
    type Err = ZenohError;

    fn from_str(text: &str) -> Result<Endpoint, ZenohError> {
        if text.starts_with("tls/") {
            return Err(ZenohError(format!(
                "{text:?}: the lab's network takes certificates over quic/HOST:PORT, not tls/ (Zenoh's TLS link can drop a busy peer, eclipse-zenoh/zenoh#2557)"
            )));
        }
        let fits = text
            .strip_prefix("tcp/")
            .or_else(|| text.strip_prefix(SECURED))
            .and_then(|address| {
                let (host, port) = address.rsplit_once(':')?;
                (!host.is_empty() && port.parse::<u16>().is_ok()).then_some(())
            });
        match fits {
            Some(()) => Ok(Endpoint(text.to_owned())),
            None => Err(ZenohError(format!(
                "{text:?} is no Zenoh endpoint: give quic/HOST:PORT (or tcp/HOST:PORT), e.g. quic/127.0.0.1:7447"
            ))),
        }
    }
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Where a cell or gateway meets the others on Zenoh.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ZenohOptions {
    /// Endpoints to connect to: a gateway's router, or a site's `zenohd`.
    pub connect: Vec<Endpoint>,
    /// Endpoints an embedded router listens on (a gateway's, with no
    /// `connect`).
    pub listen: Vec<Endpoint>,
    /// Who may join, and as whom this session joins.
    pub trust: ZenohTrust,
}

/// How peers on a Zenoh network know each other.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ZenohTrust {
    /// Anyone who reaches the endpoints (ROS 2's default): for a network on
    /// this machine alone, or one a site secures itself.
    #[default]
    Open,
    /// A gateway's router: members' certificates only, each its own keys.
    Router(Arc<RouterTrust>),
    /// A member joining with the credentials a gateway issued.
    Member(Arc<ZenohCredentials>),
}

impl ZenohOptions {
    /// Whether it opens a router anyone beyond this machine can join
    /// unauthenticated: said loudly at start and in `/status`.
    pub fn open_beyond_loopback(&self) -> bool {
        self.trust == ZenohTrust::Open && self.listen.iter().any(|e| !e.is_loopback())
    }
}

impl ZenohOptions {
    /// A client of the router these options make, on this machine: a
    /// second session beside it (a cell's ROS 2 side beside its robot's).
    pub fn local_client(&self) -> ZenohOptions {
        if !self.connect.is_empty() {
            return self.clone();
        }
        let connect = self
            .listen
            .iter()
            .map(|e| {
                Endpoint(
                    e.0.replace("/0.0.0.0:", "/127.0.0.1:")
                        .replace("/[::]:", "/[::1]:"),
                )
            })
            .collect();
        ZenohOptions {
            connect,
            listen: Vec::new(),
            trust: ZenohTrust::Open,
        }
    }
}

/// A cell joining a gateway.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CellOptions {
    pub name: vl_core::CellName,
    pub zenoh: ZenohOptions,
}

/// Why Zenoh would not open.
#[derive(Debug, thiserror::Error)]
#[error("Zenoh: {0}")]
pub struct ZenohError(String);

impl From<zenoh::Error> for ZenohError {
    fn from(e: zenoh::Error) -> ZenohError {
        ZenohError(e.to_string())
    }
}

/// How long a silent peer (a dead machine, a pulled cable) keeps its
/// place: its liveliness tokens go after this. Not shorter: a busy machine
/// (two cores, a gateway pushing frames to 150 watchers) has been seen
/// to go a second without a keep-alive, and a cell taken for lost ends
/// its runs. The robot does not wait for it: its leash stops it.
pub(crate) const LEASE: Duration = Duration::from_secs(3);

/// A Zenoh session: a router listening on `listen` when nothing is given
/// to connect to, else a client of `connect` (retried until it answers).
/// No multicast scouting: a lab's cells join the gateway they are told.
pub async fn open(options: &ZenohOptions) -> Result<zenoh::Session, ZenohError> {
    let mut config = zenoh::Config::default();
    let json = |v: &[Endpoint]| {
        let v: Vec<String> = v.iter().map(Endpoint::for_zenoh).collect();
        serde_json::to_string(&v).unwrap_or_else(|_| "[]".into())
    };
    let set = |config: &mut zenoh::Config, key: &str, value: &str| {
        config
            .insert_json5(key, value)
            .map_err(|e| ZenohError(format!("{key} = {value}: {e}")))
    };
    let endpoints = options.connect.iter().chain(&options.listen);
    match &options.trust {
        ZenohTrust::Open => {}
        ZenohTrust::Router(trust) => {
            set(&mut config, "transport/link/tls", &trust.tls().to_string())?;
            set(
                &mut config,
                "access_control",
                &trust.access_control().to_string(),
            )?;
        }
        ZenohTrust::Member(credentials) => {
            set(
                &mut config,
                "transport/link/tls",
                &credentials.tls().to_string(),
            )?;
        }
    }
    let secured = options.trust != ZenohTrust::Open;
    if let Some(wrong) = endpoints.clone().find(|e| e.is_secured() != secured) {
        return Err(ZenohError(if secured {
            format!("{wrong} shows no certificates: a network of certificates takes quic/HOST:PORT")
        } else {
            format!("{wrong} needs certificates (--zenoh-credentials), or give tcp/HOST:PORT")
        }));
    }
    // Only the protocol given: scouting would open others.
    let protocol = if secured { "[\"quic\"]" } else { "[\"tcp\"]" };
    set(&mut config, "transport/link/protocols", protocol)?;
    if options.connect.is_empty() {
        set(&mut config, "mode", "\"router\"")?;
        set(&mut config, "listen/endpoints", &json(&options.listen))?;
    } else {
        set(&mut config, "mode", "\"client\"")?;
        set(&mut config, "connect/endpoints", &json(&options.connect))?;
        // Wait for the router however long it takes to come up.
        set(&mut config, "connect/timeout_ms", "-1")?;
        set(&mut config, "connect/exit_on_failure", "false")?;
    }
    set(&mut config, "scouting/multicast/enabled", "false")?;
    set(&mut config, "scouting/gossip/enabled", "false")?;
    set(
        &mut config,
        "transport/link/tx/lease",
        &LEASE.as_millis().to_string(),
    )?;
    set(&mut config, "transport/link/tx/keep_alive", "4")?;
    Ok(zenoh::open(config).await?)
}

/// Whether `sample` holds at most `most` bytes, checked before it is read;
/// one that holds more is dropped, said at most once a second.
pub fn within(sample: &zenoh::sample::Sample, most: usize, hush: &vl_host::Hush) -> bool {
    let size = sample.payload().len();
    if size <= most {
        return true;
    }
    if hush.speak() {
        tracing::warn!(
            "{} carried {size} bytes, over the {most} it may: dropped",
            sample.key_expr()
        );
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_are_tcp_or_quic_and_quic_goes_on_one_stream() {
        let quic: Endpoint = "quic/127.0.0.1:7447".parse().unwrap();
        assert!(quic.is_secured() && quic.is_loopback());
        assert_eq!(quic.for_zenoh(), "quic/127.0.0.1:7447?multistream=0");
        let tcp: Endpoint = "tcp/[::1]:7447".parse().unwrap();
        assert_eq!(
            (tcp.host(), tcp.for_zenoh().as_str()),
            ("::1", "tcp/[::1]:7447")
        );
        let refused = "tls/10.0.0.2:7447".parse::<Endpoint>().unwrap_err().0;
        assert!(refused.contains("quic/HOST:PORT"), "{refused}");
        for bad in ["udp/1.2.3.4:1", "quic/:7447", "quic/host", "tcp/h:99999"] {
            assert!(bad.parse::<Endpoint>().is_err(), "{bad}");
        }
    }
}
