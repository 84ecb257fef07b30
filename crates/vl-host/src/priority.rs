//! Threads whose work may wait — the camera's frames, password checks,
//! forecasts — run below the Host's others, so a busy machine still
//! serves the control loop, the operator's commands and the pings first.

use tracing::debug;

/// Lowers the calling thread's priority by `nice` levels (Linux sets nice
/// per thread); `what` names the thread in the log when it cannot.
pub(crate) fn yield_to_control(nice: i32, what: &str) {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: gettid and setpriority only read their arguments; a
        // failure leaves the priority as it was, which is only slower.
        let done = unsafe {
            let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
            libc::setpriority(libc::PRIO_PROCESS, tid, nice)
        };
        if done != 0 {
            debug!("the {what} thread keeps its priority");
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (nice, what);
}
