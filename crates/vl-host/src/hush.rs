//! Warnings about what others send, let through once a second: a flood of
//! bad samples must not become a flood of log lines.

/// Lets a warning about what others send through once a second.
#[derive(Default)]
pub struct Hush(std::sync::Mutex<Option<std::time::Instant>>);

impl Hush {
    /// Whether this warning may be said now (none was this last second).
    pub fn speak(&self) -> bool {
        let mut last = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let quiet = last.is_none_or(|at| at.elapsed() >= std::time::Duration::from_secs(1));
        if quiet {
            *last = Some(std::time::Instant::now());
        }
        quiet
    }
}
