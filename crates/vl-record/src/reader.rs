//! Reading a run's file back — whole, or as far as a crash let it be
//! written — and rewriting a damaged one whole (`repair`).

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;
use serde::Serialize;
use thiserror::Error;
use vl_core::{
    Definition, Feedback, FrameHeader, HostMessage, ImageFormat, MountedLab, RecordingName,
    Summary, Wire,
};
use vl_report::table::{Report, Table};

use super::Topic;
use crate::attached;
use crate::records::{Damage, Record, records};
use tracing::debug;

/// The largest file read back.
const MAX_FILE_BYTES: u64 = 8 << 30;

#[derive(Debug, Error)]
pub enum RecordError {
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    #[error("the MCAP library: {0}")]
    Mcap(#[from] mcap::McapError),
    #[error("{0} is not an MCAP recording (it does not start with MCAP's magic)")]
    NotMcap(PathBuf),
    #[error("{0} is {1} bytes, over the {MAX_FILE_BYTES}-byte limit for reading a run")]
    TooLarge(PathBuf, u64),
    #[error("no data directory to keep recordings in: give --recordings DIR")]
    NoDataDir,
    #[error("no recording \"{0}\" that you may see")]
    Unknown(RecordingName),
    #[error("{0} is still being recorded: ask again once the run has ended")]
    StillWriting(RecordingName),
    #[error("offset {offset} is past the recording's end at {total} bytes")]
    PastEnd { offset: u64, total: u64 },
    #[error("{0} holds no run (no /lab channel): not a recording of vl's")]
    NotARun(PathBuf),
    #[error(
        "the recordings folder reached its limit (--keep-gb): this run's file may grow to {0} bytes and no further"
    )]
    FolderFull(u64),
    #[error("{file}: {why}")]
    Attachment { file: PathBuf, why: String },
}

impl RecordError {
    /// Whether this is the disk (or the file size the system allows) full.
    pub fn is_disk_full(&self) -> bool {
        let io = match self {
            RecordError::Io(_, e) => e,
            RecordError::Mcap(mcap::McapError::Io(e)) => e,
            _ => return false,
        };
        matches!(
            io.kind(),
            std::io::ErrorKind::StorageFull | std::io::ErrorKind::FileTooLarge
        )
    }
}

/// A channel as the file declares it.
#[derive(Debug, Clone)]
struct Channel {
    topic: String,
    message_encoding: String,
    schema: Option<(String, String, Vec<u8>)>,
}

/// One message read back.
#[derive(Debug, Clone)]
pub struct Message {
    pub topic: String,
    /// When it was logged, ns since 1970.
    pub log_ns: u64,
    pub publish_ns: u64,
    pub data: Vec<u8>,
    channel: u16,
}

/// A recorded run, read as far as it was written.
#[derive(Debug, Clone)]
pub struct Recording {
    pub path: PathBuf,
    pub messages: Vec<Message>,
    /// Attachments by name (the definition, the robot, the lab, the Host's settings).
    pub attachments: BTreeMap<String, Vec<u8>>,
    pub metadata: BTreeMap<String, String>,
    /// Whether the file was finished (its footer written); a crashed
    /// Host's is not.
    pub complete: bool,
    /// The first damage met: reading stopped there, or (a chunk that
    /// does not decompress) went on past it.
    pub damaged: Option<Damage>,
    pub bytes: u64,
    channels: BTreeMap<u16, Channel>,
}

impl Recording {
    /// Reads `path` up to its end, or to damage it cannot read past.
    pub fn open(path: &Path) -> Result<Recording, RecordError> {
        let io = |e| RecordError::Io(path.to_owned(), e);
        let bytes = std::fs::metadata(path).map_err(io)?.len();
        if bytes > MAX_FILE_BYTES {
            return Err(RecordError::TooLarge(path.to_owned(), bytes));
        }
        let buf = std::fs::read(path).map_err(io)?;
        Recording::read(path, &buf)
    }

    /// Reads a file's bytes, `buf`, read from `path`, up to their end or
    /// damage it cannot read past: whatever the bytes, this returns.
    pub fn read(path: &Path, buf: &[u8]) -> Result<Recording, RecordError> {
        if !buf.starts_with(mcap::MAGIC) {
            return Err(RecordError::NotMcap(path.to_owned()));
        }
        let bytes = buf.len() as u64;
        let mut recording = Recording {
            path: path.to_owned(),
            messages: Vec::new(),
            attachments: BTreeMap::new(),
            metadata: BTreeMap::new(),
            complete: false,
            damaged: None,
            bytes,
            channels: BTreeMap::new(),
        };
        let mut schemas = BTreeMap::new();
        let magic = mcap::MAGIC.len();
        for record in records(&buf[magic..], magic) {
            let record = match record {
                Ok(Record::Chunk(content)) => {
                    for inner in records(&content, 0) {
                        match inner {
                            Ok(inner) => recording.take(inner, &mut schemas),
                            Err(damage) => {
                                recording.damaged.get_or_insert(damage);
                                break;
                            }
                        }
                    }
                    continue;
                }
                Ok(record) => record,
                Err(damage) => {
                    recording.damaged.get_or_insert(damage);
                    continue;
                }
            };
            if record == Record::Footer {
                recording.complete = true;
            }
            recording.take(record, &mut schemas);
        }
        if let Some(damage) = &recording.damaged {
            debug!(path = %path.display(), "read up to damage: {damage}");
        }
        recording.messages.sort_by_key(|m| m.log_ns);
        Ok(recording)
    }

    fn take(&mut self, record: Record<'_>, schemas: &mut BTreeMap<u16, (String, String, Vec<u8>)>) {
        match record {
            Record::Schema {
                id,
                name,
                encoding,
                data,
            } => {
                schemas.insert(id, (name, encoding, data.to_vec()));
            }
            Record::Channel {
                id,
                schema_id,
                topic,
                message_encoding,
            } => {
                self.channels.insert(
                    id,
                    Channel {
                        topic,
                        message_encoding,
                        schema: schemas.get(&schema_id).cloned(),
                    },
                );
            }
            Record::Message {
                channel_id,
                log_ns,
                publish_ns,
                data,
            } => {
                if let Some(channel) = self.channels.get(&channel_id) {
                    self.messages.push(Message {
                        topic: channel.topic.clone(),
                        log_ns,
                        publish_ns,
                        data: data.to_vec(),
                        channel: channel_id,
                    });
                }
            }
            Record::Attachment { name, data } => {
                self.attachments.insert(name, data.to_vec());
            }
            Record::Metadata(m) => self.metadata.extend(m),
            Record::Chunk(_) | Record::Footer | Record::Other => {}
        }
    }

    /// The messages on `topic`.
    pub fn on(&self, topic: &str) -> impl Iterator<Item = &Message> {
        self.messages.iter().filter(move |m| m.topic == topic)
    }

    /// Each round trip the Host measured: when (ns since 1970), and ms.
    pub fn round_trips(&self) -> Vec<(u64, f64)> {
        self.on(Topic::RoundTrip.name())
            .filter_map(|m| {
                let value: serde_json::Value = serde_json::from_slice(&m.data).ok()?;
                Some((m.log_ns, value["ms"].as_f64()?))
            })
            .collect()
    }

    /// The definition the run was started with.
    pub fn definition(&self) -> Result<Definition, RecordError> {
        self.attached_json(attached::DEFINITION)
    }

    /// The lab as mounted for the run: its arena, robot and camera.
    pub fn lab(&self) -> Result<MountedLab, RecordError> {
        self.attached_json(attached::LAB)
    }

    /// The user's controller that drove the run, its file as sent.
    pub fn controller(&self) -> Option<&[u8]> {
        [attached::CONTROLLER_WASM, attached::CONTROLLER_WAT]
            .iter()
            .find_map(|name| self.attachments.get(*name))
            .map(Vec::as_slice)
    }

    fn attached_json<T: serde::de::DeserializeOwned>(&self, name: &str) -> Result<T, RecordError> {
        let why = |why: String| RecordError::Attachment {
            file: self.path.clone(),
            why,
        };
        let bytes = (self.attachments.get(name)).ok_or_else(|| {
            why(format!(
                "it has no {name}, which a Host records with every run"
            ))
        })?;
        serde_json::from_slice(bytes).map_err(|e| why(format!("its {name}: {e}")))
    }

    /// The run's first feedback, as its Guests were sent it: where the
    /// Host had the robot when the run began.
    pub fn first_feedback(&self) -> Option<Feedback> {
        self.on(Topic::Feedback.name()).find_map(|m| {
            match HostMessage::decode(std::str::from_utf8(&m.data).ok()?).ok()? {
                HostMessage::Feedback(feedback) => Some(feedback),
                _ => None,
            }
        })
    }

    /// The run's summary, as its Guests were sent it.
    pub fn summary(&self) -> Option<Summary> {
        self.on(Topic::Summary.name()).find_map(|m| {
            match HostMessage::decode(std::str::from_utf8(&m.data).ok()?).ok()? {
                HostMessage::Done { summary } => Some(*summary),
                _ => None,
            }
        })
    }

    /// The run as its Guests got it, in order: each message of the
    /// protocol, or a camera frame on the wire, with its time (ns since
    /// 1970). `vl guest --replay` plays this.
    pub fn replay(&self) -> Result<Vec<(u64, Replayed)>, RecordError> {
        if self.on(Topic::Lab.name()).next().is_none() {
            return Err(RecordError::NotARun(self.path.clone()));
        }
        let replayed: Vec<&str> = Topic::REPLAYED.iter().map(|t| t.name()).collect();
        let mut seq = 0;
        let start = self.messages.first().map_or(0, |m| m.log_ns);
        Ok(self
            .messages
            .iter()
            .filter_map(|m| {
                if m.topic == Topic::Camera.name() {
                    seq += 1;
                    let frame = camera_frame(&m.data, seq, m.publish_ns.saturating_sub(start))?;
                    return Some((m.log_ns, Replayed::Frame(frame)));
                }
                if !replayed.contains(&m.topic.as_str()) {
                    return None;
                }
                let message = HostMessage::decode(std::str::from_utf8(&m.data).ok()?).ok()?;
                Some((m.log_ns, Replayed::Message(message)))
            })
            .collect())
    }

    /// What the file holds.
    pub fn info(&self) -> RecordingInfo {
        let mut topics: BTreeMap<&str, TopicCount> = BTreeMap::new();
        for m in &self.messages {
            let channel = &self.channels[&m.channel];
            topics
                .entry(&channel.topic)
                .or_insert_with(|| TopicCount {
                    topic: channel.topic.clone(),
                    schema: channel
                        .schema
                        .as_ref()
                        .map_or(String::new(), |s| s.0.clone()),
                    messages: 0,
                })
                .messages += 1;
        }
        let span = match (self.messages.first(), self.messages.last()) {
            (Some(a), Some(b)) => (b.log_ns - a.log_ns) as f64 * 1e-9,
            _ => 0.0,
        };
        RecordingInfo {
            file: self.path.display().to_string(),
            bytes: self.bytes,
            complete: self.complete,
            damage: self.damaged.as_ref().map(ToString::to_string),
            seconds: span,
            feedback_seconds: span_of(self.on(Topic::Feedback.name())),
            metadata: self.metadata.clone(),
            attachments: self.attachments.keys().cloned().collect(),
            topics: topics.into_values().collect(),
            summary: self.summary(),
        }
    }
}

fn span_of<'a>(messages: impl Iterator<Item = &'a Message>) -> f64 {
    let times: Vec<u64> = messages.map(|m| m.log_ns).collect();
    match (times.first(), times.last()) {
        (Some(a), Some(b)) => (b - a) as f64 * 1e-9,
        _ => 0.0,
    }
}

/// One thing a replay feeds the Guest.
#[derive(Debug, Clone)]
pub enum Replayed {
    Message(HostMessage),
    /// A camera frame as the wire carries it.
    Frame(Vec<u8>),
}

/// A recorded `foxglove.CompressedImage` back as the wire's frame.
fn camera_frame(data: &[u8], seq: u64, since_start_ns: u64) -> Option<Vec<u8>> {
    use base64::Engine;
    let value: serde_json::Value = serde_json::from_slice(data).ok()?;
    let jpeg = base64::engine::general_purpose::STANDARD
        .decode(value["data"].as_str()?)
        .ok()?;
    let (width, height) = image::ImageReader::new(std::io::Cursor::new(&jpeg))
        .with_guessed_format()
        .ok()?
        .into_dimensions()
        .ok()?;
    let header = FrameHeader {
        format: ImageFormat::Jpeg,
        width: u16::try_from(width).ok()?,
        height: u16::try_from(height).ok()?,
        seq,
        event: 0,
        capture_us: since_start_ns / 1000,
    };
    Some(header.encode(&jpeg))
}

/// Messages on one channel.
#[derive(Debug, Clone, Serialize)]
pub struct TopicCount {
    pub topic: String,
    pub schema: String,
    pub messages: usize,
}

/// What `vl record info` says of a file.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingInfo {
    pub file: String,
    pub bytes: u64,
    pub complete: bool,
    /// The first damage met, and where.
    pub damage: Option<String>,
    /// From the first message to the last, s.
    pub seconds: f64,
    /// From the first feedback to the last, s.
    pub feedback_seconds: f64,
    pub metadata: BTreeMap<String, String>,
    pub attachments: Vec<String>,
    pub topics: Vec<TopicCount>,
    pub summary: Option<Summary>,
}

impl Report for RecordingInfo {
    fn table(&self) -> Table {
        let ending = self.summary.as_ref().map_or_else(
            || "not recorded (the Host stopped first?)".to_owned(),
            Summary::ending,
        );
        let finished = if self.complete {
            "finished"
        } else {
            "unfinished: `vl record repair` rewrites it whole"
        };
        let mut table = Table::columns(&["channel", "schema", "messages"])
            .title(format!(
                "{}: {:.1} MB, {finished}",
                self.file,
                self.bytes as f64 / 1e6
            ))
            .title(format!(
                "{:.1} s recorded, {:.1} s of feedback; the run: {ending}",
                self.seconds, self.feedback_seconds
            ));
        if let Some(damage) = &self.damage {
            table = table.title(format!("damaged: {damage}"));
        }
        for (key, value) in &self.metadata {
            table = table.title(format!("{key}: {value}"));
        }
        for t in &self.topics {
            table.row(vec![
                t.topic.clone(),
                t.schema.clone(),
                t.messages.to_string(),
            ]);
        }
        table.note(format!("attached: {}", self.attachments.join(", ")))
    }
}

/// What `repair` kept.
#[derive(Debug, Clone, Serialize)]
pub struct Repaired {
    pub from: String,
    pub to: String,
    pub messages: usize,
    pub feedback_seconds: f64,
    /// Whether the file was damaged or unfinished (else it was copied whole).
    pub was_complete: bool,
}

impl Report for Repaired {
    fn table(&self) -> Table {
        Table::pairs([
            ("from", self.from.clone()),
            ("to", self.to.clone()),
            ("messages kept", self.messages.to_string()),
            ("feedback kept", format!("{:.1} s", self.feedback_seconds)),
            (
                "was finished",
                if self.was_complete { "yes" } else { "no" }.to_owned(),
            ),
        ])
    }
}

/// Rewrites `from` — as far as it can be read — as a finished file at `to`
/// (by default beside it, as `NAME-repaired.mcap`).
pub fn repair(from: &Path, to: Option<&Path>) -> Result<Repaired, RecordError> {
    let recording = Recording::open(from)?;
    let stem = from.file_stem().unwrap_or_default().to_string_lossy();
    let beside = from.with_file_name(format!("{stem}-repaired.mcap"));
    let to = to.unwrap_or(&beside);
    let file = std::fs::File::create(to).map_err(|e| RecordError::Io(to.to_owned(), e))?;
    let mut writer = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .profile("")
        .create(BufWriter::new(file))?;
    writer.write_metadata(&mcap::records::Metadata {
        name: "run".into(),
        metadata: recording.metadata.clone(),
    })?;
    for (name, data) in &recording.attachments {
        writer.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: name.clone(),
            media_type: "application/json".into(),
            data: data.as_slice().into(),
        })?;
    }
    let mut ids = BTreeMap::new();
    for (&old, channel) in &recording.channels {
        let schema = match &channel.schema {
            Some((name, encoding, data)) => writer.add_schema(name, encoding, data)?,
            None => 0,
        };
        let id = writer.add_channel(
            schema,
            &channel.topic,
            &channel.message_encoding,
            &BTreeMap::new(),
        )?;
        ids.insert(old, id);
    }
    for (sequence, m) in recording.messages.iter().enumerate() {
        writer.write_to_known_channel(
            &MessageHeader {
                channel_id: ids[&m.channel],
                sequence: sequence as u32,
                log_time: m.log_ns,
                publish_time: m.publish_ns,
            },
            &m.data,
        )?;
    }
    writer.finish()?;
    Ok(Repaired {
        from: from.display().to_string(),
        to: to.display().to_string(),
        messages: recording.messages.len(),
        feedback_seconds: span_of(recording.on(Topic::Feedback.name())),
        was_complete: recording.complete && recording.damaged.is_none(),
    })
}
