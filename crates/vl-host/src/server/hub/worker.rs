//! Work the hub hands off its own task, newest first: a potential field
//! for a definition's virtual obstacles, a definition's forecast. One job
//! runs at a time on a thread of its own (which it may lower below the
//! control loop's priority); a job asked for while one runs
//! waits in place of any before it, and the running one is told it is no
//! longer wanted. However many definitions a client sends, the hub never
//! waits and at most one thread works per kind of job.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use tokio::sync::mpsc;
use tracing::warn;

/// A job: given the flag that says it is no longer wanted.
type Job<T> = Box<dyn FnOnce(&AtomicBool) -> T + Send>;

pub(super) struct JobThread<T> {
    /// What the job's threads are named.
    name: &'static str,
    /// The number of the newest job asked for.
    asked: u64,
    /// The running job's "no longer wanted" flag, if one runs.
    running: Option<Arc<AtomicBool>>,
    waiting: Option<(u64, Job<T>)>,
    done_tx: mpsc::UnboundedSender<(u64, T)>,
    pub(super) done: mpsc::UnboundedReceiver<(u64, T)>,
}

impl<T: Send + 'static> JobThread<T> {
    pub(super) fn new(name: &'static str) -> JobThread<T> {
        let (done_tx, done) = mpsc::unbounded_channel();
        JobThread {
            name,
            asked: 0,
            running: None,
            waiting: None,
            done_tx,
            done,
        }
    }

    /// Asks for `job`; what was asked before is no longer wanted.
    pub(super) fn ask(&mut self, job: impl FnOnce(&AtomicBool) -> T + Send + 'static) {
        self.forget();
        self.waiting = Some((self.asked, Box::new(job)));
        self.next();
    }

    /// Starts the waiting job if none runs.
    fn next(&mut self) {
        if self.running.is_some() {
            return;
        }
        let Some((number, job)) = self.waiting.take() else {
            return;
        };
        let cancel = Arc::new(AtomicBool::new(false));
        self.running = Some(cancel.clone());
        let done = self.done_tx.clone();
        let spawned = std::thread::Builder::new()
            .name(self.name.to_owned())
            .spawn(move || {
                let _ = done.send((number, job(&cancel)));
            });
        if let Err(e) = spawned {
            // Nothing will end it: the next ask tries again.
            warn!("cannot start a {} thread: {e}", self.name);
            self.running = None;
        }
    }

    /// A job ended: what it made, if it is the newest asked for.
    pub(super) fn finished(&mut self, number: u64, made: T) -> Option<T> {
        self.running = None;
        self.next();
        (number == self.asked).then_some(made)
    }

    /// Whatever runs or waits is no longer wanted.
    pub(super) fn forget(&mut self) {
        self.asked += 1;
        self.waiting = None;
        if let Some(running) = &self.running {
            running.store(true, Ordering::Relaxed);
        }
    }
}
