//! The lab as an LTI 1.3 tool inside a teacher's LMS (Moodle, Canvas,
//! Blackboard, Brightspace): the platforms it trusts and its own key
//! (`registry`), the OIDC login and the checked launch that let a person
//! in without a password (`launch`), the sessions those launches open
//! (`sessions`), the platform's services the tool calls — grades (AGS)
//! and the course's roster (NRPS) over OAuth2 client credentials
//! (`services`) — and the pages on the Host's port (`pages`).
//!
//! Every signature is made and checked by `jsonwebtoken`; every call to a
//! platform goes through `reqwest`, bounded in time and size.

mod deep_link;
mod grades;
mod launch;
pub(crate) mod pages;
mod registry;
mod roster;
mod services;
pub(crate) mod sessions;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use registry::{Platform, Registry, ToolKey, key_path, registry_path};
pub(crate) use sessions::Sessions;
use vl_core::{Experiments, Rubric};

use std::net::IpAddr;

use vl_core::HostStatus;

use vl_host::Audit;
use vl_host::LabHandle;
use vl_host::SessionCheck;
use vl_host::{Extension, ExtensionTask};

/// Why the LMS side of a lab cannot be set up or used.
#[derive(Debug, thiserror::Error)]
pub enum LtiError {
    #[error("{0}: {1}")]
    File(PathBuf, String),
    #[error("{0}")]
    Registration(String),
    #[error("cannot sign: {0}")]
    Sign(String),
    #[error("the platform: {0}")]
    Platform(String),
}

/// The claims of LTI 1.3 and its services, by their names in the
/// specifications.
mod claim {
    pub(super) const MESSAGE_TYPE: &str = "https://purl.imsglobal.org/spec/lti/claim/message_type";
    pub(super) const VERSION: &str = "https://purl.imsglobal.org/spec/lti/claim/version";
    pub(super) const DEPLOYMENT_ID: &str =
        "https://purl.imsglobal.org/spec/lti/claim/deployment_id";
    pub(super) const ROLES: &str = "https://purl.imsglobal.org/spec/lti/claim/roles";
    pub(super) const CONTEXT: &str = "https://purl.imsglobal.org/spec/lti/claim/context";
    pub(super) const CUSTOM: &str = "https://purl.imsglobal.org/spec/lti/claim/custom";
    pub(super) const AGS: &str = "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint";
    pub(super) const NRPS: &str = "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice";
    pub(super) const DEEP_LINKING: &str =
        "https://purl.imsglobal.org/spec/lti-dl/claim/deep_linking_settings";
    pub(super) const CONTENT_ITEMS: &str =
        "https://purl.imsglobal.org/spec/lti-dl/claim/content_items";
    pub(super) const DATA: &str = "https://purl.imsglobal.org/spec/lti-dl/claim/data";
    pub(super) const SCORE_SCOPE: &str = "https://purl.imsglobal.org/spec/lti-ags/scope/score";
    pub(super) const ROSTER_SCOPE: &str =
        "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly";
}

/// `m`'s lock, even if a thread panicked holding it (what it guards is
/// bookkeeping, whole after each change).
fn locked<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Puts `value` in `map` under `key`, first making room when `map` holds
/// `most`: the entry `age` finds oldest goes.
fn insert_bounded<K, V, A: Ord>(
    map: &mut std::collections::HashMap<K, V>,
    most: usize,
    key: K,
    value: V,
    age: impl Fn(&V) -> A,
) where
    K: std::hash::Hash + Eq + Clone,
{
    if map.len() >= most && !map.contains_key(&key) {
        let oldest = map
            .iter()
            .min_by_key(|(_, v)| age(v))
            .map(|(k, _)| k.clone());
        if let Some(oldest) = oldest {
            map.remove(&oldest);
        }
    }
    map.insert(key, value);
}

/// What a lab's LMS side is set up with.
pub struct LtiOptions {
    /// The lab's accounts file: the platforms and the key are kept beside it.
    pub users: PathBuf,
    /// How every run is graded, whatever its experiment declares.
    pub rubric: Option<Rubric>,
    /// What the lab offers: what a link may open, and each experiment's
    /// rubric.
    pub experiments: Experiments,
}

/// The lab's LMS side: its platforms, key, pending logins, sessions and grades.
pub struct Lti {
    registry: PathBuf,
    key: ToolKey,
    logins: launch::Logins,
    sessions: Arc<Sessions>,
    http: reqwest::Client,
    audit: Audit,
    grades: grades::GradeBook,
    tokens: services::AccessTokens,
    experiments: Experiments,
}

impl Lti {
    /// The LMS side of the lab whose accounts are in `options.users`: its
    /// key made now if it has none. Built on a runtime (its HTTP client).
    pub fn new(options: LtiOptions, audit: Audit) -> Result<Arc<Lti>, LtiError> {
        let registry = registry_path(&options.users);
        Registry::load(&registry)?;
        let key = ToolKey::load_or_make(&key_path(&options.users))?;
        Ok(Arc::new(Lti {
            registry,
            key,
            logins: launch::Logins::default(),
            sessions: Arc::new(Sessions::default()),
            http: services::client()?,
            audit,
            grades: grades::GradeBook::new(options.rubric, &options.experiments),
            experiments: options.experiments,
            tokens: services::AccessTokens::default(),
        }))
    }

    /// The platforms as their file has them now (changes count at once).
    fn platforms(&self) -> Result<Registry, LtiError> {
        Registry::load(&self.registry)
    }

    /// Whether the lab has an LMS side at `users`: a platform registered
    /// (a platforms file that does not read is an error, never no LMS).
    pub fn registered(users: &Path) -> Result<bool, LtiError> {
        Registry::load(&registry_path(users)).map(|r| !r.platforms.is_empty())
    }
}

impl std::fmt::Debug for Lti {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lti")
            .field("registry", &self.registry)
            .field("kid", &self.key.kid)
            .finish_non_exhaustive()
    }
}

impl Extension for Lti {
    fn routes(self: Arc<Self>, address: IpAddr) -> axum::Router {
        pages::routes(self, address)
    }

    fn sessions(&self) -> Option<Arc<dyn SessionCheck>> {
        Some(self.sessions.clone())
    }

    fn status(&self, status: &mut HostStatus) {
        status.grades = Some(self.grades_status());
    }

    fn run(self: Arc<Self>, lab: LabHandle) -> ExtensionTask {
        Box::pin(self.grade_runs(lab.events.listen()))
    }
}
