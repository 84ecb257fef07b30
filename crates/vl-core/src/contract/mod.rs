//! What Guest and Host agree on: the messages of protocol v1 and the
//! camera frames between them, a run's summary, the experiments and their definitions, and
//! recorded runs and their parts on the wire, the session supervisor that says which action may happen when (with the
//! access net that says who may drive), and the fingerprint a Guest pins a
//! Host's certificate by, and the one colour legend both ends draw with.

pub(crate) mod access;
pub(crate) mod cells;
pub(crate) mod definition;
pub(crate) mod experiment;
pub(crate) mod fingerprint;
pub(crate) mod forecast;
pub(crate) mod frame;
pub(crate) mod host_status;
pub(crate) mod legend;
pub(crate) mod protocol;
pub(crate) mod recording;
pub(crate) mod rubric;
pub(crate) mod summary;
pub(crate) mod supervisor;
pub(crate) mod transport;
