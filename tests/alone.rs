//! The tests that time the lab under attack or through hiccups: each needs
//! the machine's cores to itself, so that what it times is the lab's, not a
//! busy test runner's. Cargo runs one test binary at a time, and the tests
//! here take turns.

#[allow(dead_code)] // this binary uses a part of what the tests share
mod common;

mod disk_full;
mod floods;
mod gateway;
mod hiccups;
mod ros2;
mod stalls;

use tokio::sync::{Mutex, MutexGuard};

/// Held by each test here for its whole run: one at a time.
async fn alone() -> MutexGuard<'static, ()> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::const_new(());
    ONE_AT_A_TIME.lock().await
}
