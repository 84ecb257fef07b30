//! The process's log: to stderr as `RUST_LOG` says (warnings by default),
//! and — whatever `RUST_LOG` says — the Host's own lines of INFO and above
//! into the run being recorded, as `foxglove.Log`, so a run's file says
//! what the Host saw happen during it.

use std::fmt::Write as _;
use std::sync::{Arc, Mutex, Weak};

use tracing::field::{Field, Visit};
use tracing_subscriber::layer::{Context, Layer};
use tracing_subscriber::prelude::*;

use super::foxglove::Level;
use super::writer::{Entry, Feed, Shared};

/// The recorders of this process (one a Host), held weakly: a Host that
/// ends takes its recorder with it.
static RECORDERS: Mutex<Vec<Weak<Shared>>> = Mutex::new(Vec::new());

/// Hands the Host's log to `feed`'s recorder from now on.
pub(super) fn register(feed: &Feed) {
    let Some(recorder) = feed.shared() else {
        return;
    };
    let mut recorders = RECORDERS.lock().unwrap_or_else(|e| e.into_inner());
    recorders.retain(|r| r.strong_count() > 0);
    recorders.push(Arc::downgrade(recorder));
}

/// Sets the process's log up: stderr, and the runs being recorded.
pub fn init_logging() {
    let stderr = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        // Colour codes only where a terminal shows them, not in a log file.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        );
    // Only the Host's lines of INFO and above are ever made for the
    // recordings: a debug line elsewhere costs nothing more than before.
    let host =
        tracing_subscriber::filter::Targets::new().with_target("vl_host", tracing::Level::INFO);
    tracing_subscriber::registry()
        .with(stderr)
        .with(IntoRecordings.with_filter(host))
        .init();
}

/// Hands the Host's log lines to the runs being recorded.
struct IntoRecordings;

/// An event's message and fields as one line.
struct Line(String);

impl Visit for Line {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.0, "{value:?}");
        } else {
            let _ = write!(self.0, " {}={value:?}", field.name());
        }
    }
}

impl<S: tracing::Subscriber> Layer<S> for IntoRecordings {
    fn on_event(&self, event: &tracing::Event<'_>, _: Context<'_, S>) {
        let meta = event.metadata();
        let level = match *meta.level() {
            tracing::Level::ERROR => Level::Error,
            tracing::Level::WARN => Level::Warning,
            _ => Level::Info,
        };
        let recorders = RECORDERS.lock().unwrap_or_else(|e| e.into_inner());
        let recording: Vec<Arc<Shared>> = recorders
            .iter()
            .filter_map(Weak::upgrade)
            .filter(|r| r.active())
            .collect();
        drop(recorders);
        if recording.is_empty() {
            return;
        }
        let mut line = Line(String::new());
        event.record(&mut line);
        for recorder in recording {
            recorder.put(Entry::Log(level, line.0.clone()));
        }
    }
}
