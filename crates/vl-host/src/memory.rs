//! Memory given back to the system when a client leaves: what a burst of
//! clients made the allocator take (frames read and queued for them) stays
//! in its free lists otherwise, and the Host or the Media looks as large as
//! its worst minute for the rest of the day.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

/// At most once a second: trimming walks the heap, and clients that
/// connect and leave in a flood must not make the process do it each time.
const AT_MOST_EVERY_MS: u64 = 1000;

/// Returns free memory to the system, unless that was done within the last
/// second.
pub(crate) fn give_back() {
    static LAST_MS: AtomicU64 = AtomicU64::new(0);
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    let last = LAST_MS.load(Ordering::Relaxed);
    if now.saturating_sub(last) < AT_MOST_EVERY_MS
        || LAST_MS
            .compare_exchange(last, now, Ordering::Relaxed, Ordering::Relaxed)
            .is_err()
    {
        return;
    }
    trim();
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn trim() {
    // SAFETY: malloc_trim only walks and releases glibc's own free lists.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Other allocators give memory back by themselves, or offer no way to ask.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn trim() {}
