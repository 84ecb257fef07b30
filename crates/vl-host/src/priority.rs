//! Who gets the processor first. The control loop and the serial guard
//! ask for a real-time priority (or at least a raised one), so a busy
//! machine still extends the robot's leash in time; the threads whose work
//! may wait — the camera's frames, password checks, forecasts, the
//! recorder — run below the Host's others.

use tracing::debug;
use vl_core::Priority;

/// The real-time level the control loop and the guard ask for (of 1–99):
/// above ordinary threads, below the kernel's own.
const REAL_TIME_LEVEL: i32 = 20;
/// Failing that, the nice value they ask for.
const RAISED_NICE: i32 = -10;

/// Raises the calling thread (Linux sets the policy and nice per thread)
/// as far as the system allows: real-time, else a negative nice, else not
/// at all; `what` names it in the log. Nothing fails for want of it.
pub fn raise_for_control(what: &str) -> Priority {
    #[cfg(target_os = "linux")]
    {
        let param = libc::sched_param {
            sched_priority: REAL_TIME_LEVEL,
        };
        // SAFETY: sched_setscheduler and setpriority only read their
        // arguments; pid/tid 0 and gettid name the calling thread, and a
        // refusal leaves its priority as it was.
        let (real_time, raised) = unsafe {
            let real_time = libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) == 0;
            let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
            let raised = !real_time && libc::setpriority(libc::PRIO_PROCESS, tid, RAISED_NICE) == 0;
            (real_time, raised)
        };
        let got = if real_time {
            Priority::RealTime {
                level: REAL_TIME_LEVEL,
            }
        } else if raised {
            Priority::Raised { nice: RAISED_NICE }
        } else {
            Priority::Normal
        };
        debug!("the {what} runs at {got}");
        got
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = what;
        Priority::Normal
    }
}

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
