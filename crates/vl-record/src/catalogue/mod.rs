//! The recordings folder: where each run's file goes, the entry beside it
//! that says whose run it is and how it ended, who may see which, and what
//! the retention limits let go.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, SystemTime};

use serde::{Deserialize, Serialize};
use tracing::{info, warn};
use vl_core::{PART_BYTES, RecordedRun, RecordingName};
use vl_report::table::{Report, Table};

use super::RecordError;
use index::Index;

mod index;

/// The most runs a Guest is sent in one list.
const MOST_LISTED: usize = 100;

/// Where and how long the Host keeps its runs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecordSettings {
    /// Where every run is recorded (default: vl/recordings in the user's
    /// data directory).
    pub recordings: Option<PathBuf>,
    /// Record nothing.
    pub no_record: bool,
    /// Delete recordings older than this many days, oldest first.
    pub keep_days: Option<f64>,
    /// Keep at most this many GB of recordings, deleting the oldest first.
    pub keep_gb: Option<f64>,
    /// Record the time between runs too, not only the runs.
    pub record_idle: bool,
}

/// vl's folder in this user's data directory (`$XDG_DATA_HOME/vl`, else
/// `~/.local/share/vl`): the Host's recordings, the Guest's downloads.
pub fn data_dir() -> Option<PathBuf> {
    let data = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")))?;
    Some(data.join("vl"))
}

/// Where a Host records when not told (`vl/recordings` in the data
/// directory).
pub fn recordings_dir() -> Option<PathBuf> {
    Some(data_dir()?.join("recordings"))
}

/// Milliseconds since 1970.
pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_millis() as u64
}

impl RecordSettings {
    /// The folder runs go to, made if missing; none with `--no-record`.
    pub fn catalogue(&self) -> Result<Option<Catalogue>, RecordError> {
        if self.no_record {
            return Ok(None);
        }
        let mut catalogue = Catalogue::at(self.recordings.as_deref())?;
        catalogue.keep_days = self.keep_days;
        catalogue.keep_gb = self.keep_gb;
        catalogue.record_idle = self.record_idle;
        Ok(Some(catalogue))
    }
}

/// The runs of a folder, as `vl record ls` lists them.
#[derive(Debug, Clone, Serialize)]
pub struct Runs(pub Vec<RecordedRun>);

impl Report for Runs {
    fn table(&self) -> Table {
        // When it started tells the runs of one Host's day from another's
        // (each Host numbers its runs from 1).
        let mut table = Table::columns(&[
            "file",
            "started",
            "run",
            "experiment",
            "who",
            "s",
            "MB",
            "ending",
        ]);
        for r in &self.0 {
            table.row(vec![
                r.name.to_string(),
                vl_report::table::utc(r.started_ms),
                r.run.to_string(),
                r.experiment
                    .as_ref()
                    .map_or_else(|| "between runs".into(), |e| e.to_string()),
                r.user.clone().unwrap_or_else(|| "anonymous".into()),
                r.seconds.map_or_else(|| "-".into(), |s| format!("{s:.1}")),
                format!("{:.1}", r.bytes as f64 / 1e6),
                r.ending
                    .map_or_else(|| "unfinished".into(), |e| e.to_string()),
            ]);
        }
        table.note(format!("{} runs", self.0.len()))
    }
}

/// Who a run is: the account that drove it, else the one connection
/// (this Host's start and the connection's number) that did.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Owner {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub user: Option<String>,
    pub connection: String,
}

impl Owner {
    /// Whether someone who is `self` may see a run `of` owns.
    fn sees(&self, of: &Owner) -> bool {
        match (&self.user, &of.user) {
            (Some(me), Some(them)) => me == them,
            (None, None) => self.connection == of.connection,
            _ => false,
        }
    }
}

/// The entry kept beside each run's file.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct CatalogueEntry {
    run: RecordedRun,
    owner: Owner,
}

/// A recordings folder.
#[derive(Debug, Clone)]
pub struct Catalogue {
    dir: PathBuf,
    keep_days: Option<f64>,
    keep_gb: Option<f64>,
    /// When this Host opened it, ms since 1970: a connection's number is
    /// only this Host's.
    opened_ms: u64,
    /// The file being written now, which cannot be downloaded yet.
    writing: Arc<Mutex<Option<RecordingName>>>,
    /// Whether the time between runs is recorded too.
    pub record_idle: bool,
    /// The entries, read from the folder once and kept.
    index: Arc<Mutex<Index>>,
}

impl Catalogue {
    /// The folder at `dir`, made if it does not exist.
    pub fn open(dir: &Path) -> Result<Catalogue, RecordError> {
        std::fs::create_dir_all(dir).map_err(|e| RecordError::Io(dir.to_owned(), e))?;
        Ok(Catalogue {
            dir: dir.to_owned(),
            keep_days: None,
            keep_gb: None,
            opened_ms: now_ms(),
            writing: Arc::default(),
            record_idle: false,
            index: Arc::default(),
        })
    }

    /// Who someone on connection `connection` is, with the account `user`.
    pub fn owner(&self, user: Option<&str>, connection: u64) -> Owner {
        Owner {
            user: user.map(str::to_owned),
            connection: format!("{}-{connection}", self.opened_ms),
        }
    }

    /// The folder at `dir`, else the user's (made if missing).
    pub fn at(dir: Option<&Path>) -> Result<Catalogue, RecordError> {
        match dir {
            Some(dir) => Catalogue::open(dir),
            None => Catalogue::open(&recordings_dir().ok_or(RecordError::NoDataDir)?),
        }
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Says which file is being written (none: no file).
    pub fn writing(&self, name: Option<&RecordingName>) {
        *self.writing.lock().unwrap_or_else(|e| e.into_inner()) = name.cloned();
    }

    pub fn path(&self, name: &RecordingName) -> PathBuf {
        self.dir.join(name.as_str())
    }

    fn entry_path(&self, name: &RecordingName) -> PathBuf {
        self.dir.join(format!("{}.json", name.as_str()))
    }

    /// The entries, read from the folder the first time.
    fn index(&self) -> MutexGuard<'_, Index> {
        let mut index = self.index.lock().unwrap_or_else(|e| e.into_inner());
        index.read_once(&self.dir);
        index
    }

    /// Keeps `run`'s entry, with its file's size now.
    pub fn write_entry(&self, run: &RecordedRun, owner: &Owner) -> Result<(), RecordError> {
        let path = self.entry_path(&run.name);
        let mut entry = CatalogueEntry {
            run: run.clone(),
            owner: owner.clone(),
        };
        entry.run.bytes = self.size(&run.name).unwrap_or(0);
        let text = serde_json::to_vec_pretty(&entry).expect("entries serialise");
        // Written aside and renamed into place: a `vl record ls` reading
        // the folder meanwhile reads the old entry or the new, never half.
        let aside = path.with_extension("json.new");
        std::fs::write(&aside, text)
            .and_then(|()| std::fs::rename(&aside, &path))
            .map_err(|e| RecordError::Io(path, e))?;
        self.index().put(entry);
        Ok(())
    }

    /// The size of `name`'s file now, if it is there.
    fn size(&self, name: &RecordingName) -> Option<u64> {
        std::fs::metadata(self.path(name)).ok().map(|m| m.len())
    }

    /// `entries` with their files' sizes now; those whose file is gone
    /// left out.
    fn sized(&self, entries: Vec<CatalogueEntry>) -> Vec<RecordedRun> {
        entries
            .into_iter()
            .filter_map(|mut e| {
                e.run.bytes = self.size(&e.run.name)?;
                Some(e.run)
            })
            .collect()
    }

    /// Every recorded run, newest first.
    pub fn runs(&self) -> Runs {
        let entries: Vec<CatalogueEntry> = self.index().iter().cloned().collect();
        Runs(self.sized(entries))
    }

    /// The newest runs `who` may see (their own, or every one for an
    /// administrator), at most `MOST_LISTED`: the list fits one message.
    /// Only those listed are looked at on disk.
    pub fn visible(&self, who: &Owner, admin: bool) -> Vec<RecordedRun> {
        let entries: Vec<CatalogueEntry> = self
            .index()
            .iter()
            .filter(|e| admin || who.sees(&e.owner))
            .take(MOST_LISTED)
            .cloned()
            .collect();
        self.sized(entries)
    }

    /// The part of recording `name` from `offset` on, and the file's
    /// length, if `who` may see it.
    pub fn part(
        &self,
        name: &RecordingName,
        offset: u64,
        who: &Owner,
        admin: bool,
    ) -> Result<(u64, Vec<u8>), RecordError> {
        let known = self
            .index()
            .get(name)
            .is_some_and(|e| admin || who.sees(&e.owner));
        if !known {
            return Err(RecordError::Unknown(name.clone()));
        }
        if self
            .writing
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            == Some(name)
        {
            return Err(RecordError::StillWriting(name.clone()));
        }
        use std::io::{Read, Seek, SeekFrom};
        let path = self.path(name);
        let io = |e| RecordError::Io(path.clone(), e);
        let mut file = std::fs::File::open(&path).map_err(io)?;
        let total = file.metadata().map_err(io)?.len();
        if offset > total {
            return Err(RecordError::PastEnd { offset, total });
        }
        file.seek(SeekFrom::Start(offset)).map_err(io)?;
        let mut bytes = Vec::with_capacity(PART_BYTES.min((total - offset) as usize));
        file.take(PART_BYTES as u64)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        Ok((total, bytes))
    }

    /// Deletes the runs older than `--keep-days`, and the oldest past
    /// `--keep-gb` (counting `running` as it is now), never `running`.
    pub fn retain(&self, running: &RecordingName) {
        if let Some(days) = self.keep_days {
            let max_age_ms = (days * 86_400e3) as u64;
            let now_ms = now_ms();
            let old: Vec<RecordingName> = self
                .index()
                .iter()
                .filter(|e| {
                    &e.run.name != running && now_ms.saturating_sub(e.run.started_ms) > max_age_ms
                })
                .map(|e| e.run.name.clone())
                .collect();
            for name in old {
                self.delete(&name, "older than the retention limit (--keep-days)");
            }
        }
        let now = self.size(running).unwrap_or(0);
        self.room(running, now);
    }

    /// How large the file `running` may grow under `--keep-gb` (none: no
    /// limit) once it is `wanted` bytes: the oldest other runs are deleted
    /// while the folder would pass the limit.
    pub fn room(&self, running: &RecordingName, wanted: u64) -> Option<u64> {
        let most = self.limit()?;
        // Newest first; the stored sizes (the running file is not among them).
        let mut others: Vec<(RecordingName, u64)> = self
            .index()
            .iter()
            .filter(|e| &e.run.name != running)
            .map(|e| (e.run.name.clone(), e.run.bytes))
            .collect();
        let mut total: u64 = others.iter().map(|(_, bytes)| bytes).sum();
        while wanted.saturating_add(total) > most {
            let Some((oldest, bytes)) = others.pop() else {
                break;
            };
            self.delete(&oldest, "past the folder's limit (--keep-gb)");
            total -= bytes;
        }
        Some(most.saturating_sub(total))
    }

    /// Deletes run `name`'s file and entry.
    pub(crate) fn delete(&self, name: &RecordingName, why: &str) {
        info!(recording = %name, "deleted: {why}");
        self.index().remove(name);
        for path in [self.path(name), self.entry_path(name)] {
            match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    warn!("could not delete {}: {e}", path.display());
                }
                _ => {}
            }
        }
    }

    /// The limit on the folder, bytes.
    pub(crate) fn limit(&self) -> Option<u64> {
        self.keep_gb.map(|gb| (gb * 1e9) as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::ExperimentId;

    const DAY_MS: u64 = 86_400_000;

    /// A folder holding a run of 1,000 bytes begun `age_ms` ago for each
    /// `(age_ms, owner)`, numbered from 1.
    fn folder(test: &str, runs: &[(u64, &Owner)]) -> (Catalogue, Vec<RecordingName>) {
        let dir = std::env::temp_dir().join(format!("vl-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let catalogue = Catalogue::open(&dir).unwrap();
        let names = runs
            .iter()
            .zip(1..)
            .map(|(&(age_ms, owner), run)| {
                let started_ms = now_ms() - age_ms;
                let name = RecordingName::of_run(started_ms, run);
                std::fs::write(catalogue.path(&name), [0u8; 1000]).unwrap();
                let recorded = RecordedRun {
                    name: name.clone(),
                    run,
                    experiment: Some(ExperimentId::new("navigation").unwrap()),
                    started_ms,
                    user: owner.user.clone(),
                    ending: None,
                    seconds: None,
                    bytes: 0,
                };
                catalogue.write_entry(&recorded, owner).unwrap();
                name
            })
            .collect();
        (catalogue, names)
    }

    fn names(runs: Vec<RecordedRun>) -> Vec<RecordingName> {
        runs.into_iter().map(|r| r.name).collect()
    }

    #[test]
    fn the_oldest_go_first_and_the_one_running_never() {
        let owner = Owner {
            user: None,
            connection: "1-1".into(),
        };
        let (mut catalogue, runs) = folder(
            "retain",
            &[(10 * DAY_MS, &owner), (5 * DAY_MS, &owner), (0, &owner)],
        );
        catalogue.keep_days = Some(7.0);
        // The ten-day-old run is the one being written: it stays.
        catalogue.retain(&runs[0]);
        assert_eq!(names(catalogue.runs().0).len(), 3);
        catalogue.retain(&runs[2]);
        assert_eq!(
            names(catalogue.runs().0),
            vec![runs[2].clone(), runs[1].clone()]
        );
        assert!(!catalogue.path(&runs[0]).exists(), "its file stayed");
        // 1.5 kB: only the newest run fits.
        catalogue.keep_days = None;
        catalogue.keep_gb = Some(1.5e-6);
        catalogue.retain(&runs[2]);
        assert_eq!(names(catalogue.runs().0), vec![runs[2].clone()]);
        let _ = std::fs::remove_dir_all(catalogue.dir());
    }

    #[test]
    fn each_sees_their_own_runs_and_an_administrator_all() {
        let ada = Owner {
            user: Some("ada".into()),
            connection: "1-1".into(),
        };
        let anonymous = Owner {
            user: None,
            connection: "1-2".into(),
        };
        let (catalogue, runs) = folder("visible", &[(2, &ada), (1, &anonymous)]);
        let ada_again = Owner {
            connection: "2-9".into(),
            ..ada.clone()
        };
        assert_eq!(
            names(catalogue.visible(&ada_again, false)),
            vec![runs[0].clone()]
        );
        assert_eq!(
            names(catalogue.visible(&anonymous, false)),
            vec![runs[1].clone()]
        );
        let stranger = Owner {
            user: None,
            connection: "1-3".into(),
        };
        assert!(catalogue.visible(&stranger, false).is_empty());
        assert!(catalogue.part(&runs[1], 0, &stranger, false).is_err());
        assert_eq!(catalogue.visible(&stranger, true).len(), 2);
        let (total, bytes) = catalogue.part(&runs[1], 200, &anonymous, false).unwrap();
        assert_eq!((total, bytes.len()), (1000, 800));
        let _ = std::fs::remove_dir_all(catalogue.dir());
    }
}
