//! What a job costs in memory: a global allocator that counts live and
//! peak heap bytes once switched on (a program installs it with
//! `#[global_allocator]` and calls [`Counting::switch_on`] only where it
//! measures memory, so a server's hot loops pay one plain load per
//! allocation, not two atomic updates), and the process's peak resident
//! memory as the kernel counts it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering};

/// Where the peak heap use of a benchmark comes from: the binary's
/// allocator, which a library cannot own.
pub trait PeakMemory {
    /// Starts a new peak measurement from what is live now.
    fn reset_peak(&self);
    /// The most bytes live at once since the last reset.
    fn peak_bytes(&self) -> usize;
}

/// The system allocator, counting once switched on: install it as the
/// program's global allocator for [`peak_bytes`] and [`PeakMemory`] to
/// see the heap.
pub struct Counting;

static ON: AtomicBool = AtomicBool::new(false);
/// Signed: blocks allocated before the switch may be freed after it.
static LIVE: AtomicIsize = AtomicIsize::new(0);
static PEAK: AtomicIsize = AtomicIsize::new(0);

impl Counting {
    /// Counts from now on, for the rest of the process.
    pub fn switch_on() {
        ON.store(true, Ordering::Relaxed);
    }
}

fn grew(bytes: usize) {
    if ON.load(Ordering::Relaxed) {
        let bytes = bytes as isize;
        let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
        PEAK.fetch_max(live, Ordering::Relaxed);
    }
}

fn shrank(bytes: usize) {
    if ON.load(Ordering::Relaxed) {
        LIVE.fetch_sub(bytes as isize, Ordering::Relaxed);
    }
}

// SAFETY: every call is passed straight to the system allocator; the
// counters are only bookkeeping.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        shrank(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            shrank(layout.size());
            grew(new_size);
        }
        p
    }
}

/// The most heap bytes live at once since counting was switched on.
pub fn peak_bytes() -> usize {
    PEAK.load(Ordering::Relaxed).max(0) as usize
}

/// The most memory the process has held resident, bytes (what `time -v`
/// calls the maximum resident set size): heap, mapped memory, code, stacks
/// and all. On Linux it is the program's own high-water mark: getrusage's
/// also counts what the process that started it held before the exec.
pub fn peak_resident_bytes() -> usize {
    #[cfg(target_os = "linux")]
    if let Some(kb) = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
            line.trim()
                .trim_end_matches("kB")
                .trim()
                .parse::<usize>()
                .ok()
        })
    {
        return kb * 1024;
    }
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage fills the struct it is given; RUSAGE_SELF is valid.
    let usage = unsafe {
        libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr());
        usage.assume_init()
    };
    usize::try_from(usage.ru_maxrss).unwrap_or(0) * 1024
}

/// Benchmarks in the libraries measure through the allocator.
impl PeakMemory for Counting {
    fn reset_peak(&self) {
        PEAK.store(LIVE.load(Ordering::Relaxed), Ordering::Relaxed);
    }

    fn peak_bytes(&self) -> usize {
        peak_bytes()
    }
}
