//! Recorded runs fetched from the Host: a download asks for one part at a
//! time from where the file so far ends, so it is paced by the Guest and
//! picks up where a dropped one stopped (the part file is kept).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use thiserror::Error;
use vl_core::{ErrorCode, GuestMessage, HostMessage, PartHeader, RecordingName};

use crate::client::{Connection, Incoming};

/// How long to wait before asking again for a file still being written.
const STILL_WRITING_WAIT: std::time::Duration = std::time::Duration::from_millis(200);

#[derive(Debug, Error)]
pub enum DownloadError {
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    #[error("the Host refused the download: {message} ({code})")]
    Refused { code: ErrorCode, message: String },
    #[error("the connection ended during the download")]
    Closed,
    #[error("gave up waiting for {0}")]
    Timeout(RecordingName),
    #[error("the Host sent a part at {got} where {wanted} was asked for")]
    OutOfPlace { got: u64, wanted: u64 },
    #[error("the Host recorded no file of the run to download")]
    NotRecorded,
}

/// Downloads the recording of the run `summary` ends into `dir`, when
/// there is a folder to download into; with `progress` said on stderr,
/// given up at the deadline.
pub(crate) async fn download_run(
    connection: &mut Connection,
    dir: Option<&Path>,
    summary: &vl_core::Summary,
    (progress, deadline): (bool, Instant),
) -> Result<Option<PathBuf>, DownloadError> {
    let Some(dir) = dir else {
        return Ok(None);
    };
    let note = summary
        .recording
        .as_ref()
        .ok_or(DownloadError::NotRecorded)?;
    download(connection, &note.name, dir, progress, deadline)
        .await
        .map(Some)
}

/// A download under way: the file so far, and how long the whole is.
pub struct Downloading {
    pub name: RecordingName,
    part: PathBuf,
    file: std::fs::File,
    pub have: u64,
    /// The file's length, once a part has said it.
    pub total: Option<u64>,
    /// When to ask again for a file the Host was still writing.
    pub retry_at: Option<std::time::Instant>,
}

impl Downloading {
    /// Starts, or resumes from the part file `dir` already holds.
    pub fn open(name: &RecordingName, dir: &Path) -> Result<Downloading, DownloadError> {
        std::fs::create_dir_all(dir).map_err(|e| DownloadError::Io(dir.to_owned(), e))?;
        let part = dir.join(format!("{name}.part"));
        let io = |e| DownloadError::Io(part.clone(), e);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&part)
            .map_err(io)?;
        let have = file.metadata().map_err(io)?.len();
        Ok(Downloading {
            name: name.clone(),
            part,
            file,
            have,
            total: None,
            retry_at: None,
        })
    }

    /// The message asking for the next part.
    pub fn ask(&self) -> GuestMessage {
        GuestMessage::Download {
            name: self.name.clone(),
            offset: self.have,
        }
    }

    /// Takes a part in; true once the file is whole.
    pub fn take(&mut self, header: &PartHeader, bytes: &[u8]) -> Result<bool, DownloadError> {
        if header.offset != self.have {
            return Err(DownloadError::OutOfPlace {
                got: header.offset,
                wanted: self.have,
            });
        }
        self.file
            .write_all(bytes)
            .map_err(|e| DownloadError::Io(self.part.clone(), e))?;
        self.have += bytes.len() as u64;
        self.total = Some(header.total);
        Ok(self.have >= header.total)
    }

    /// The whole file, in `dir` under its name.
    pub fn finish(self) -> Result<PathBuf, DownloadError> {
        let whole = self.part.with_file_name(self.name.as_str());
        std::fs::rename(&self.part, &whole).map_err(|e| DownloadError::Io(whole.clone(), e))?;
        Ok(whole)
    }
}

/// Where this user's downloaded runs go: vl/downloads in their data
/// directory.
pub fn downloads_dir() -> Option<PathBuf> {
    Some(vl_record::data_dir()?.join("downloads"))
}

/// Downloads recording `name` into `dir` over `connection`, saying how far
/// it has come on stderr when `progress`; the file's path once whole.
pub async fn download(
    connection: &mut Connection,
    name: &RecordingName,
    dir: &Path,
    progress: bool,
    deadline: Instant,
) -> Result<PathBuf, DownloadError> {
    let mut downloading = Downloading::open(name, dir)?;
    connection.send(downloading.ask());
    let mut told = Instant::now();
    loop {
        let incoming = tokio::time::timeout_at(deadline.into(), connection.recv())
            .await
            .map_err(|_| DownloadError::Timeout(name.clone()))?;
        match incoming {
            Some(Incoming::Part(header, bytes)) if &header.name == name => {
                if downloading.take(&header, &bytes)? {
                    return downloading.finish();
                }
                if progress && told.elapsed().as_secs_f64() >= 1.0 {
                    told = Instant::now();
                    eprintln!(
                        "downloading {name}: {:.1} of {:.1} MB",
                        downloading.have as f64 / 1e6,
                        header.total as f64 / 1e6
                    );
                }
                connection.send(downloading.ask());
            }
            Some(Incoming::Message(message)) => match *message {
                // The run's file is being closed: it is whole in a moment.
                HostMessage::Error {
                    code: ErrorCode::NotAllowedNow,
                    ..
                } => {
                    tokio::time::sleep(STILL_WRITING_WAIT).await;
                    connection.send(downloading.ask());
                }
                HostMessage::Error { code, message } => {
                    return Err(DownloadError::Refused { code, message });
                }
                _ => {}
            },
            Some(Incoming::Closed(_)) | None => return Err(DownloadError::Closed),
            Some(_) => {}
        }
    }
}
