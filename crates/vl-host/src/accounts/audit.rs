//! The audit log: who did what at the lab, one JSON object a line —
//! logins and failures, roles taken and given up, runs and their ends,
//! refusals. Written by its own task from a bounded queue, so no session
//! ever waits on the disk; what a full queue cannot take is counted and
//! said in the log when there is room again.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::Serialize;
use tokio::sync::mpsc;
use tracing::warn;

/// Entries waiting to be written, at most.
const QUEUE: usize = 1024;

/// One thing that happened, as the log's line says it.
#[derive(Debug, Clone, Serialize)]
pub struct AuditEntry {
    /// Milliseconds since 1970 (UTC).
    pub at_ms: u64,
    /// What happened: `login` (detail: the role, or `status`),
    /// `login_failed`, `rate_limited`, `welcome`, `refused` (a hello, and
    /// why), `takeover_refused` (another account's resume secret), `queued`, `granted`, `slot_ended`, `kicked`, `released`,
    /// `run_started`, `run_ended` (with the driver), `reset` (the drive
    /// back to the start, numbered as runs are), `accounts_read`, and the
    /// devices' faults and returns.
    pub event: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub connection: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub user: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

impl AuditEntry {
    pub fn new(event: &'static str) -> AuditEntry {
        AuditEntry {
            at_ms: SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_millis() as u64),
            event,
            connection: None,
            user: None,
            address: None,
            detail: None,
        }
    }

    pub fn connection(mut self, id: u64) -> AuditEntry {
        self.connection = Some(id);
        self
    }

    pub fn user(mut self, user: Option<&str>) -> AuditEntry {
        self.user = user.map(str::to_owned);
        self
    }

    pub fn address(mut self, address: impl ToString) -> AuditEntry {
        self.address = Some(address.to_string());
        self
    }

    pub fn detail(mut self, detail: impl Into<String>) -> AuditEntry {
        self.detail = Some(detail.into());
        self
    }
}

/// Where entries go; cloning it shares the log. Without a file it only
/// keeps nothing (a lab run without `--audit`).
#[derive(Debug, Clone, Default)]
pub struct Audit {
    queue: Option<mpsc::Sender<AuditEntry>>,
    dropped: Arc<AtomicU64>,
}

impl Audit {
    /// A log appended to `path`, by a task on the current runtime; the
    /// file is the lab manager's alone (0600: it says who logged in from
    /// where), made so or narrowed so.
    pub fn open(path: &Path) -> std::io::Result<Audit> {
        use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .mode(0o600)
            .open(path)?;
        file.set_permissions(std::fs::Permissions::from_mode(0o600))?;
        let (queue, entries) = mpsc::channel(QUEUE);
        let dropped = Arc::new(AtomicU64::new(0));
        let writer = Writer {
            path: path.to_owned(),
            file: std::io::BufWriter::new(file),
            dropped: dropped.clone(),
        };
        tokio::task::spawn_blocking(move || writer.run(entries));
        Ok(Audit {
            queue: Some(queue),
            dropped,
        })
    }

    /// Logs `entry`, without waiting: a full queue counts it as dropped.
    pub fn record(&self, entry: AuditEntry) {
        if let Some(queue) = &self.queue
            && queue.try_send(entry).is_err()
        {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

struct Writer {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    dropped: Arc<AtomicU64>,
}

impl Writer {
    fn run(mut self, mut entries: mpsc::Receiver<AuditEntry>) {
        while let Some(entry) = entries.blocking_recv() {
            let dropped = self.dropped.swap(0, Ordering::Relaxed);
            if dropped > 0 {
                self.line(&AuditEntry::new("dropped").detail(format!("{dropped} entries")));
            }
            self.line(&entry);
            // Each line on disk as it happens: the log outlives a crash.
            if entries.is_empty() && self.file.flush().is_err() {
                warn!("cannot write the audit log {}", self.path.display());
            }
        }
        let _ = self.file.flush();
    }

    fn line(&mut self, entry: &AuditEntry) {
        if let Ok(text) = serde_json::to_string(entry)
            && writeln!(self.file, "{text}").is_err()
        {
            warn!("cannot write the audit log {}", self.path.display());
        }
    }
}
