//! The sessions LMS launches open: a secret the launched page carries (in
//! its `vl-session` meta tag, sent in its hello as `session`: an LMS frames
//! the tool, where browsers block third-party cookies) standing for the
//! person the platform vouched for, with what their launch said — their
//! role, course, line item and roster service — for grades and the roster.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::time::Instant;

use vl_host::AccountRole;
use vl_host::{Identity, SessionCheck, SessionId};

/// Sessions kept at once, at most; the oldest go first.
const MAX_SESSIONS: usize = 10_000;
/// Sessions one person keeps at once (a page per browser and device, and
/// some): launching again past this ends their own oldest, never anyone
/// else's.
const MAX_PER_PERSON: usize = 8;
/// How long a launch's session lasts.
const LIFETIME: Duration = Duration::from_secs(8 * 3600);

/// What the teacher chose for the link (deep linking): the experiment,
/// and a goal.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Assignment {
    pub experiment: Option<String>,
    pub goal: Option<String>,
}

/// Where a deep-linking request wants its answer.
#[derive(Debug, Clone)]
pub(crate) struct DeepLinking {
    pub return_url: String,
    pub data: Option<String>,
}

/// What a checked launch said about its person and where they came from.
#[derive(Debug, Clone)]
pub(crate) struct Launch {
    pub issuer: String,
    pub client_id: String,
    pub deployment_id: String,
    /// Who they are at the platform (the token's `sub`).
    pub sub: String,
    /// Who they are at the lab: `sub@platform-host`.
    pub user: String,
    /// Their name, when the platform gave it.
    pub person: Option<String>,
    pub role: AccountRole,
    /// The course's title.
    pub course: Option<String>,
    /// The line item their runs are graded in, when the platform lets
    /// the tool post scores there.
    pub lineitem: Option<String>,
    /// The course's members (NRPS), when the platform offers them.
    pub memberships: Option<String>,
    pub assignment: Assignment,
    /// For an instructor's deep-linking request: where to answer.
    pub deep_linking: Option<DeepLinking>,
}

impl Launch {
    pub(crate) fn identity(&self) -> Identity {
        Identity::Lms {
            name: self.user.clone(),
            role: self.role,
        }
    }
}

struct Entry {
    id: SessionId,
    launch: Arc<Launch>,
    until: Instant,
}

/// The open sessions, by their secrets.
#[derive(Default)]
pub(crate) struct Sessions {
    open: Mutex<HashMap<String, Entry>>,
    /// The last session's number.
    opened: AtomicU64,
}

impl Sessions {
    /// Opens a session for `launch`: its secret.
    pub(crate) fn open(&self, launch: Launch) -> String {
        let secret = vl_host::secret();
        let launch = Arc::new(launch);
        let id = SessionId(self.opened.fetch_add(1, Ordering::Relaxed) + 1);
        let now = Instant::now();
        let mut open = super::locked(&self.open);
        open.retain(|_, e| e.until > now);
        let theirs = |e: &Entry| e.launch.user == launch.user;
        if open.values().filter(|e| theirs(e)).count() >= MAX_PER_PERSON {
            let oldest = open
                .iter()
                .filter(|(_, e)| theirs(e))
                .min_by_key(|(_, e)| e.until)
                .map(|(k, _)| k.clone());
            if let Some(oldest) = oldest {
                open.remove(&oldest);
            }
        }
        let entry = Entry {
            id,
            launch,
            until: now + LIFETIME,
        };
        super::insert_bounded(&mut open, MAX_SESSIONS, secret.clone(), entry, |e| e.until);
        secret
    }

    /// The launch of the session `secret`, while it lasts.
    pub(crate) fn launch(&self, secret: &str) -> Option<Arc<Launch>> {
        let open = super::locked(&self.open);
        open.get(secret)
            .filter(|e| e.until > Instant::now())
            .map(|e| e.launch.clone())
    }

    /// How many sessions are open.
    #[cfg(test)]
    pub(crate) fn open_count(&self) -> usize {
        super::locked(&self.open).len()
    }

    /// The launch that opened session `id`, while the session lasts.
    pub(crate) fn launch_of(&self, id: SessionId) -> Option<Arc<Launch>> {
        let now = Instant::now();
        super::locked(&self.open)
            .values()
            .find(|e| e.id == id && e.until > now)
            .map(|e| e.launch.clone())
    }
}

impl SessionCheck for Sessions {
    fn vouch(&self, secret: &str) -> Option<(Identity, SessionId)> {
        let open = super::locked(&self.open);
        open.get(secret)
            .filter(|e| e.until > Instant::now())
            .map(|e| (e.launch.identity(), e.id))
    }
}
