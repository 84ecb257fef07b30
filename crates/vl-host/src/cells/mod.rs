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

mod cell;
mod gateway;
pub(crate) mod keys;
mod link;

pub(crate) use cell::{Cell, join};
pub(crate) use gateway::serve as serve_gateway;

use std::time::Duration;

/// A Zenoh endpoint on the lab's network: `tcp/HOST:PORT`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoint(String);

impl std::str::FromStr for Endpoint {
    type Err = ZenohError;

    fn from_str(text: &str) -> Result<Endpoint, ZenohError> {
        let fits = text.strip_prefix("tcp/").and_then(|address| {
            let (host, port) = address.rsplit_once(':')?;
            (!host.is_empty() && port.parse::<u16>().is_ok()).then_some(())
        });
        match fits {
            Some(()) => Ok(Endpoint(text.to_owned())),
            None => Err(ZenohError(format!(
                "{text:?} is no Zenoh endpoint: give tcp/HOST:PORT, e.g. tcp/127.0.0.1:7447"
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
/// place: its liveliness tokens go after this.
pub(crate) const LEASE: Duration = Duration::from_millis(1000);

/// A Zenoh session: a router listening on `listen` when nothing is given
/// to connect to, else a client of `connect` (retried until it answers).
/// No multicast scouting: a lab's cells join the gateway they are told.
pub(crate) async fn open(options: &ZenohOptions) -> Result<zenoh::Session, ZenohError> {
    let mut config = zenoh::Config::default();
    let json = |v: &[Endpoint]| {
        let v: Vec<&str> = v.iter().map(|e| e.0.as_str()).collect();
        serde_json::to_string(&v).unwrap_or_else(|_| "[]".into())
    };
    let set = |config: &mut zenoh::Config, key: &str, value: &str| {
        config
            .insert_json5(key, value)
            .map_err(|e| ZenohError(format!("{key} = {value}: {e}")))
    };
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
    set(
        &mut config,
        "transport/link/tx/lease",
        &LEASE.as_millis().to_string(),
    )?;
    set(&mut config, "transport/link/tx/keep_alive", "4")?;
    Ok(zenoh::open(config).await?)
}
