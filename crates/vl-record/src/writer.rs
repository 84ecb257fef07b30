//! The recorder: a thread that writes each run's file from what the lab
//! and the hub hand it through a bounded queue, and never holds them up.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bytes::Bytes;
use mcap::records::{MessageHeader, Metadata};
use tracing::warn;

use crate::attached;
use vl_core::{
    Definition, GuestMessage, HostMessage, MountedLab, Pose, RecordedRun, RecordingName, Wire,
};

use super::Topic;
use super::catalogue::{Catalogue, Owner};
use super::foxglove::{self, Level};
use super::views::{View, Views};

/// Entries waiting for the recorder, at most…
const QUEUE: usize = 4096;
/// …of which camera frames may take no more than this: past it, frames
/// are dropped and everything else still goes in.
const FRAMES_QUEUED: usize = QUEUE / 2;
/// A chunk is closed (and so readable after a crash) at least this often:
/// twice a second, so a crash loses less than the second promised even
/// when the recorder runs late.
const FLUSH_EVERY: Duration = Duration::from_millis(500);
/// What a file's end takes beyond its chunks (the summary: schemas,
/// channels, statistics, indexes), at most, with the closing log line…
const SUMMARY_BYTES: u64 = 64 << 10;
/// …and a chunk's index in it, for each chunk.
const CHUNK_INDEX_BYTES: u64 = 512;
/// A message's record and its index entry beyond its data.
const MESSAGE_BYTES: u64 = 64;

/// What begins a run's file.
pub struct Begin {
    pub run: RecordedRun,
    pub owner: Owner,
    pub lab: MountedLab,
    pub definition: Definition,
    /// The user's controller the run drives with, its file as sent (kept
    /// so a replay or a regrade runs exactly it).
    pub controller: Option<std::sync::Arc<[u8]>>,
    /// The Host's settings, kept with the run.
    pub config: serde_json::Value,
}

/// What the recorder is handed.
pub enum Recordable {
    Begin(Box<Begin>),
    /// A message the Host sent its clients.
    Sent(HostMessage),
    /// A camera frame as sent (header and JPEG).
    Frame(Bytes),
    Command(GuestMessage),
    RoundTrip {
        connection: u64,
        ms: f64,
    },
    /// In simulation, where the robot truly is.
    Truth(Pose),
    Log(Level, String),
    /// The run's `done` has been recorded: close its file.
    End,
}

/// What the recorder and those feeding it share.
pub(crate) struct Shared {
    queue: SyncSender<(u64, Recordable)>,
    queued: AtomicUsize,
    /// A run is being recorded: only then do the loops hand anything over.
    active: AtomicBool,
    dropped_frames: AtomicU64,
    /// Nanoseconds since 1970 at the lab's clock's zero.
    since_ns: u64,
    /// The last file whose recording stopped before its run ended.
    stopped: Mutex<Option<Stopped>>,
}

/// A run's recording stopped before the run ended: the folder reached its
/// limit, or the disk is full.
#[derive(Debug, Clone, PartialEq)]
pub struct Stopped {
    pub name: RecordingName,
    pub why: String,
    /// Whether the file was kept (finished, readable up to there); a file
    /// that holds nothing of the run is deleted, entry and all.
    pub kept: bool,
}

/// A handle on the recorder; none when the Host records nothing.
#[derive(Clone, Default)]
pub struct Feed(Option<Arc<Shared>>);

impl Shared {
    pub(crate) fn active(&self) -> bool {
        self.active.load(Ordering::Relaxed)
    }

    /// Hands `entry` over if the queue has room.
    pub(crate) fn put(&self, entry: Recordable) {
        self.queued.fetch_add(1, Ordering::Relaxed);
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) =
            self.queue.try_send((now_ns(), entry))
        {
            self.queued.fetch_sub(1, Ordering::Relaxed);
        }
    }
}

/// ns since 1970 at `instant` (in the past).
pub fn unix_ns_at(instant: Instant) -> u64 {
    now_ns().saturating_sub(instant.elapsed().as_nanos() as u64)
}

pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl Feed {
    /// Starts the recorder, writing into `catalogue`'s folder; `since` is
    /// the lab's clock's zero, which frames' capture times count from.
    /// `first` runs on the recorder's thread before anything else (the Host
    /// lowers the thread's priority there: it gives way to the control loop).
    pub fn spawn(
        catalogue: Catalogue,
        since: Instant,
        first: impl FnOnce() + Send + 'static,
    ) -> Feed {
        let (queue, entries) = mpsc::sync_channel(QUEUE);
        let shared = Arc::new(Shared {
            queue,
            queued: AtomicUsize::new(0),
            active: AtomicBool::new(false),
            dropped_frames: AtomicU64::new(0),
            since_ns: unix_ns_at(since),
            stopped: Mutex::default(),
        });
        let recorder = Recorder {
            catalogue,
            entries,
            shared: shared.clone(),
            file: None,
        };
        std::thread::Builder::new()
            .name("vl-recorder".into())
            .spawn(move || {
                first();
                recorder.run();
            })
            .expect("the OS starts a thread");
        Feed(Some(shared))
    }

    /// Whether a run is being recorded.
    pub fn active(&self) -> bool {
        self.0.as_ref().is_some_and(|s| s.active())
    }

    /// Hands `entry` over, while a run is recorded.
    pub fn send(&self, entry: Recordable) {
        if let Some(shared) = self.0.as_ref().filter(|_| self.active()) {
            shared.put(entry);
        }
    }

    /// A run begins: its file opens, and from now on the loops hand over.
    pub fn begin(&self, begin: Begin) -> Option<RecordingName> {
        let shared = self.0.as_ref()?;
        let name = begin.run.name.clone();
        shared.dropped_frames.store(0, Ordering::Relaxed);
        shared.active.store(true, Ordering::Relaxed);
        shared.put(Recordable::Begin(Box::new(begin)));
        Some(name)
    }

    /// The run's `done` was handed over: its file closes.
    pub fn end(&self) {
        if let Some(shared) = &self.0 {
            shared.put(Recordable::End);
            shared.active.store(false, Ordering::Relaxed);
        }
    }

    /// A camera frame, unless the queue is half full: frames go first.
    pub fn frame(&self, wire: &Bytes) {
        let Some(shared) = self.0.as_ref().filter(|_| self.active()) else {
            return;
        };
        if shared.queued.load(Ordering::Relaxed) >= FRAMES_QUEUED {
            shared.dropped_frames.fetch_add(1, Ordering::Relaxed);
        } else {
            shared.put(Recordable::Frame(wire.clone()));
        }
    }

    /// Why the recording of `name` stopped before its run ended, if it did.
    pub fn stopped(&self, name: &RecordingName) -> Option<Stopped> {
        self.last_stopped().filter(|s| &s.name == name)
    }

    /// The last recording that stopped before its run ended.
    pub fn last_stopped(&self) -> Option<Stopped> {
        let shared = self.0.as_ref()?;
        let stopped = shared.stopped.lock().unwrap_or_else(|e| e.into_inner());
        stopped.clone()
    }

    /// Frames dropped since the run began.
    pub fn dropped_frames(&self) -> u64 {
        self.0
            .as_ref()
            .map_or(0, |s| s.dropped_frames.load(Ordering::Relaxed))
    }
}

struct Recorder {
    catalogue: Catalogue,
    entries: mpsc::Receiver<(u64, Recordable)>,
    shared: Arc<Shared>,
    file: Option<RunFile>,
}

impl Recorder {
    fn run(mut self) {
        loop {
            match self.entries.recv_timeout(FLUSH_EVERY) {
                Ok((ns, entry)) => {
                    self.shared.queued.fetch_sub(1, Ordering::Relaxed);
                    self.take(ns, entry);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if let Some(file) = &mut self.file
                && file.unflushed.is_some_and(|t| t.elapsed() >= FLUSH_EVERY)
                && let Err(e) = file.flush()
            {
                self.stop(&e);
            }
        }
        self.close();
    }

    fn take(&mut self, ns: u64, entry: Recordable) {
        let result = match entry {
            Recordable::Begin(begin) => {
                self.close();
                let name = begin.run.name.clone();
                self.catalogue.writing(Some(&name));
                self.catalogue.retain(&name);
                match RunFile::create(&self.catalogue, *begin, ns, self.shared.since_ns) {
                    Ok(file) => {
                        self.file = Some(file);
                        Ok(())
                    }
                    Err(e) => {
                        // Nothing of it was kept: no entry names a file that is not there.
                        self.catalogue.delete(&name, "it could not be begun");
                        let why = e.to_string();
                        *self
                            .shared
                            .stopped
                            .lock()
                            .unwrap_or_else(|e| e.into_inner()) = Some(Stopped {
                            name,
                            why,
                            kept: false,
                        });
                        Err(e)
                    }
                }
            }
            Recordable::End => {
                self.close();
                Ok(())
            }
            entry => match &mut self.file {
                Some(file) => file.write(ns, entry),
                None => Ok(()),
            },
        };
        if let Err(e) = result {
            self.stop(&e);
        }
    }

    /// The file under way cannot go on (the folder's limit, a full disk):
    /// it is finished as far as it goes, or deleted when it holds nothing
    /// of the run, and the Host told why.
    fn stop(&mut self, e: &super::RecordError) {
        let why = match e {
            super::RecordError::FolderFull(_) => e.to_string(),
            e if e.is_disk_full() => format!("the disk is full ({e})"),
            e => e.to_string(),
        };
        warn!("a run's recording stops: {why}");
        if let Some(file) = self.file.take() {
            let name = file.run.name.clone();
            let kept = file.stop(&self.catalogue, &why);
            if !kept {
                self.catalogue.delete(&name, "it holds nothing of its run");
            }
            *self
                .shared
                .stopped
                .lock()
                .unwrap_or_else(|e| e.into_inner()) = Some(Stopped { name, why, kept });
        }
        self.catalogue.writing(None);
    }

    fn close(&mut self) {
        if let Some(file) = self.file.take() {
            let name = file.run.name.clone();
            if let Err(e) = file.finish(&self.catalogue) {
                warn!("the recording {name} could not be closed: {e}");
            }
        }
        self.catalogue.writing(None);
    }
}

/// A writer that knows how far its file reaches: what the folder's
/// limit is checked against.
struct Counted<W> {
    inner: W,
    at: u64,
    /// Shared with the `RunFile`: the writer owns this.
    end: Arc<AtomicU64>,
}

impl<W: Write> Write for Counted<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.at += n as u64;
        self.end.fetch_max(self.at, Ordering::Relaxed);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Seek> Seek for Counted<W> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.at = self.inner.seek(to)?;
        Ok(self.at)
    }
}

/// A run's file while it is written.
struct RunFile {
    writer: mcap::Writer<Counted<BufWriter<File>>>,
    /// How far the file reaches, as handed to its buffer.
    end: Arc<AtomicU64>,
    catalogue: Catalogue,
    /// Bytes handed to the writer since its chunk last closed, with their
    /// records: what the open chunk may still add to the file.
    pending: u64,
    chunks: u64,
    /// How large the file may grow under the folder's limit (none: no limit).
    room: Option<u64>,
    channels: HashMap<Topic, u16>,
    /// The latest log time written: log times never go back.
    last_ns: u64,
    sequence: u32,
    /// When the oldest message not yet in a closed chunk was written.
    unflushed: Option<Instant>,
    run: RecordedRun,
    owner: Owner,
    views: Views,
}

type Written = Result<(), super::RecordError>;

impl RunFile {
    fn create(
        catalogue: &Catalogue,
        begin: Begin,
        ns: u64,
        since_ns: u64,
    ) -> Result<RunFile, super::RecordError> {
        let path = catalogue.path(&begin.run.name);
        let file = File::create(&path).map_err(|e| super::RecordError::Io(path.clone(), e))?;
        let end = Arc::new(AtomicU64::new(0));
        let counted = Counted {
            inner: BufWriter::new(file),
            at: 0,
            end: end.clone(),
        };
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("")
            .create(counted)?;
        let metadata = Metadata {
            name: "run".into(),
            metadata: [
                ("run".to_owned(), begin.run.run.to_string()),
                (
                    "experiment".to_owned(),
                    begin
                        .run
                        .experiment
                        .as_ref()
                        .map_or("between runs", |e| e.as_str())
                        .to_owned(),
                ),
                ("arena".to_owned(), begin.lab.scene.arena.name.clone()),
                (
                    "user".to_owned(),
                    begin.owner.user.clone().unwrap_or_default(),
                ),
                (
                    "host".to_owned(),
                    format!("vl {}", env!("CARGO_PKG_VERSION")),
                ),
            ]
            .into(),
        };
        writer.write_metadata(&metadata)?;
        for (name, media_type, data) in attachments(&begin) {
            writer.attach(&mcap::Attachment {
                log_time: ns,
                create_time: ns,
                name: name.into(),
                media_type: media_type.into(),
                data: data.into(),
            })?;
        }
        catalogue.write_entry(&begin.run, &begin.owner)?;
        let mounted = HostMessage::Mounted(Box::new(begin.lab));
        let defined = HostMessage::Defined {
            definition: begin.definition,
        };
        let mut file = RunFile {
            writer,
            end,
            catalogue: catalogue.clone(),
            pending: 0,
            chunks: 0,
            room: catalogue.room(&begin.run.name, SUMMARY_BYTES),
            channels: HashMap::new(),
            last_ns: ns,
            sequence: 0,
            unflushed: None,
            run: begin.run,
            owner: begin.owner,
            views: Views::new(since_ns, None, Definition::default()),
        };
        for message in [mounted, defined] {
            let views = file.views.sent(ns, &message);
            file.put_all(views)?;
        }
        let text = match &file.run.experiment {
            Some(experiment) => format!("run {} of {experiment} begins", file.run.run),
            None => "the time between runs".to_owned(),
        };
        file.put_all(vec![View::log(ns, Level::Info, &text)])?;
        Ok(file)
    }

    /// How large the file would be, at most, with `more` bytes of data
    /// more and its end written.
    fn reach(&self, more: u64) -> u64 {
        let ends = SUMMARY_BYTES + CHUNK_INDEX_BYTES * (self.chunks + 1);
        self.end.load(Ordering::Relaxed) + self.pending + more + MESSAGE_BYTES + ends
    }

    /// Whether `more` bytes fit under the folder's limit: older runs are
    /// let go to make room first.
    fn fits(&mut self, more: u64) -> Written {
        let Some(room) = self.room else {
            return Ok(());
        };
        let reach = self.reach(more);
        if reach <= room {
            return Ok(());
        }
        // Room for a while more, not for one message at a time.
        let wanted = reach + (room / 8).min(1 << 20);
        self.room = self.catalogue.room(&self.run.name, wanted);
        match self.room {
            Some(room) if reach > room => Err(super::RecordError::FolderFull(room)),
            _ => Ok(()),
        }
    }

    /// Writes `data` on `topic`, its channel made on first use.
    fn put(&mut self, topic: Topic, log_ns: u64, publish_ns: u64, data: &[u8]) -> Written {
        self.fits(data.len() as u64)?;
        self.put_unchecked(topic, log_ns, publish_ns, data)
    }

    /// Writes `data` on `topic` whatever the folder's limit.
    fn put_unchecked(
        &mut self,
        topic: Topic,
        log_ns: u64,
        publish_ns: u64,
        data: &[u8],
    ) -> Written {
        let channel_id = match self.channels.get(&topic) {
            Some(&id) => id,
            None => {
                let schema = topic.schema();
                let body = serde_json::to_vec(&schema.body).expect("schemas serialise");
                let schema_id = self.writer.add_schema(schema.name, "jsonschema", &body)?;
                let id = self.writer.add_channel(
                    schema_id,
                    topic.name(),
                    "json",
                    &Default::default(),
                )?;
                self.channels.insert(topic, id);
                id
            }
        };
        self.last_ns = self.last_ns.max(log_ns);
        self.sequence = self.sequence.wrapping_add(1);
        self.writer.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence: self.sequence,
                log_time: self.last_ns,
                publish_time: publish_ns,
            },
            data,
        )?;
        self.pending += data.len() as u64 + MESSAGE_BYTES;
        self.unflushed.get_or_insert_with(Instant::now);
        Ok(())
    }

    fn foxglove(&mut self, topic: Topic, ns: u64, value: &serde_json::Value) -> Written {
        let data = serde_json::to_vec(value).expect("JSON values serialise");
        self.put(topic, ns, ns, &data)
    }

    /// Writes `views`, logged when they happened (never before what is
    /// already written).
    fn put_all(&mut self, views: Vec<View>) -> Written {
        for view in views {
            self.put(view.topic, view.ns, view.ns, &view.data)?;
        }
        Ok(())
    }

    fn write(&mut self, ns: u64, entry: Recordable) -> Written {
        match entry {
            Recordable::Sent(message) => self.sent(ns, message),
            Recordable::Frame(wire) => {
                // Logged as it reached the recorder; published when taken.
                for view in self.views.frame(&wire) {
                    self.put(view.topic, ns, view.ns, &view.data)?;
                }
                Ok(())
            }
            Recordable::Command(command) => {
                self.put(Topic::Commands, ns, ns, command.encode().as_bytes())
            }
            Recordable::RoundTrip { connection, ms } => self.put_all(vec![View::round_trip(
                ns,
                crate::RoundTrip { connection, ms },
            )]),
            Recordable::Truth(pose) => {
                self.foxglove(Topic::TruePose, ns, &foxglove::pose_message(ns, pose))
            }
            Recordable::Log(level, text) => self.put_all(vec![View::log(ns, level, &text)]),
            Recordable::Begin(_) | Recordable::End => Ok(()),
        }
    }

    fn sent(&mut self, ns: u64, message: HostMessage) -> Written {
        let views = self.views.sent(ns, &message);
        self.put_all(views)?;
        if let HostMessage::Done { summary } = message {
            self.run.ending = Some(summary.reason);
            self.run.seconds = Some(summary.seconds);
            let text = format!("run {} ended: {}", self.run.run, summary.ending());
            self.put_all(vec![View::log(ns, Level::Info, &text)])?;
        }
        Ok(())
    }

    /// Closes the chunk under way, so everything so far survives a crash.
    fn flush(&mut self) -> Written {
        self.writer.flush()?;
        self.unflushed = None;
        self.pending = 0;
        self.chunks += 1;
        Ok(())
    }

    fn finish(mut self, catalogue: &Catalogue) -> Written {
        self.writer.finish()?;
        catalogue.write_entry(&self.run, &self.owner)
    }

    /// Ends the file early, saying `why` in its log if it still can:
    /// whether it was kept (it holds at least a closed chunk of the run,
    /// finished if the disk let it, else as a crash leaves it, which
    /// `repair` makes whole).
    fn stop(mut self, catalogue: &Catalogue, why: &str) -> bool {
        let text = format!("the recording stops here: {why}");
        let ns = self.last_ns;
        // Within what the summary's reserve leaves for it.
        let line = View::log(ns, Level::Warning, &text);
        let said = self.put_unchecked(line.topic, ns, ns, &line.data);
        let held = self.chunks > 0 || (said.is_ok() && self.flush().is_ok());
        if let Err(e) = self.finish(catalogue) {
            warn!("the stopped recording could not be finished: {e}");
        }
        held
    }
}

/// What a run's file keeps beside its messages: the definition, the
/// robot, the lab as mounted, the Host's settings, and the user's
/// controller when one drives.
fn attachments(begin: &Begin) -> Vec<(&'static str, &'static str, Vec<u8>)> {
    let json =
        |value: Result<Vec<u8>, serde_json::Error>| value.expect("the lab's types serialise");
    let mut attached = vec![
        (
            attached::DEFINITION,
            "application/json",
            json(serde_json::to_vec_pretty(&begin.definition)),
        ),
        (
            attached::ROBOT,
            "application/json",
            json(serde_json::to_vec_pretty(&begin.lab.scene.robot)),
        ),
        (
            attached::LAB,
            "application/json",
            json(serde_json::to_vec_pretty(&begin.lab)),
        ),
        (
            attached::CONFIG,
            "application/json",
            json(serde_json::to_vec_pretty(&begin.config)),
        ),
    ];
    if let Some(file) = &begin.controller {
        // Binary, or the text format as sent.
        attached.push(match file.starts_with(b"\0asm") {
            true => (attached::CONTROLLER_WASM, "application/wasm", file.to_vec()),
            false => (attached::CONTROLLER_WAT, "text/plain", file.to_vec()),
        });
    }
    attached
}
