//! A gateway and its cells as `vl` processes: the gateway's authority in
//! a folder of the test's own, the credentials `vl gateway issue` writes,
//! the gateway on a free port and cells joining it with them.
// The LTI tests of the `tests` binary use a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use super::{VlProcess, free_udp_port, start_vl};

/// A gateway's authority in a folder of its own, and the credentials it
/// issued, through `vl gateway issue`.
pub(crate) struct Keys(pub(crate) PathBuf);

impl Keys {
    pub(crate) fn new(tag: &str) -> Keys {
        Keys(crate::common::scratch(&format!("gateway-keys-{tag}")))
    }

    pub(crate) fn dir(&self) -> &str {
        crate::common::s(&self.0)
    }

    /// Credentials for `--cell NAME` or `--ros2 NAME` (`kind`).
    pub(crate) fn issue(&self, kind: &str, name: &str) -> PathBuf {
        let file = self.0.join(format!("{name}.toml"));
        let out = crate::common::vl(&[
            "gateway",
            "issue",
            kind,
            name,
            "--keys",
            self.dir(),
            "--out",
            crate::common::s(&file),
        ]);
        assert!(out.status.success(), "{}", crate::common::stderr(&out));
        file
    }

    /// Credentials for each cell of `names`.
    pub(crate) fn cells(&self, names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(|n| self.issue("--cell", n)).collect()
    }
}

/// A gateway on a free port, its Zenoh router on another, admitting the
/// members of `keys`: its URL and the router's endpoint.
pub(crate) fn start_gateway(keys: &Keys) -> (VlProcess, String, String) {
    start_gateway_with(keys, &[])
}

pub(crate) fn start_gateway_with(keys: &Keys, extra: &[&str]) -> (VlProcess, String, String) {
    let zenoh = format!("quic/127.0.0.1:{}", free_udp_port());
    let (gateway, url) = start_gateway_on(keys, &zenoh, extra);
    (gateway, url, zenoh)
}

/// A gateway whose Zenoh router listens at `zenoh`: its URL.
pub(crate) fn start_gateway_on(keys: &Keys, zenoh: &str, extra: &[&str]) -> (VlProcess, String) {
    let args = [
        &[
            "gateway",
            "--listen",
            "127.0.0.1:0",
            "--zenoh-listen",
            zenoh,
            "--keys",
            keys.dir(),
        ],
        extra,
    ]
    .concat();
    start_vl(&args, "vl gateway listening on ")
}

/// A simulated cell named `name` joining the gateway at `zenoh` with its
/// credentials.
pub(crate) fn start_cell(zenoh: &str, name: &str, credentials: &Path) -> VlProcess {
    start_cell_with(zenoh, name, credentials, &[])
}

pub(crate) fn start_cell_with(
    zenoh: &str,
    name: &str,
    credentials: &Path,
    extra: &[&str],
) -> VlProcess {
    let args = [
        &[
            "host",
            "--listen",
            "127.0.0.1:0",
            "--no-record",
            "--gateway",
            zenoh,
            "--cell",
            name,
            "--zenoh-credentials",
            crate::common::s(credentials),
        ],
        extra,
    ]
    .concat();
    start_vl(&args, "vl host listening on ").0
}
