//! The recordings folder's entries in memory: read from the folder once,
//! then kept as runs begin, end and are let go, so that listing the runs a
//! Guest may see costs the page it is sent, not a read of every entry.

use std::cmp::Reverse;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use vl_core::RecordingName;

use super::CatalogueEntry;

/// Newest first: by start, then run number (a name breaks ties).
type Newest = Reverse<(u64, u64, RecordingName)>;

fn newest(entry: &CatalogueEntry) -> Newest {
    Reverse((entry.run.started_ms, entry.run.run, entry.run.name.clone()))
}

/// Every run with an entry, newest first.
#[derive(Debug, Default)]
pub(super) struct Index {
    entries: BTreeMap<Newest, CatalogueEntry>,
    by_name: HashMap<RecordingName, Newest>,
    read: bool,
}

impl Index {
    /// Reads the folder's entries the first time it is asked.
    pub(super) fn read_once(&mut self, dir: &Path) {
        if std::mem::replace(&mut self.read, true) {
            return;
        }
        let Ok(listing) = std::fs::read_dir(dir) else {
            return;
        };
        for file in listing.filter_map(Result::ok) {
            if !file.file_name().to_string_lossy().ends_with(".mcap.json") {
                continue;
            }
            let Some(entry) = std::fs::read(file.path())
                .ok()
                .and_then(|text| serde_json::from_slice::<CatalogueEntry>(&text).ok())
            else {
                continue;
            };
            self.put(entry);
        }
    }

    /// Adds or replaces `entry`.
    pub(super) fn put(&mut self, entry: CatalogueEntry) {
        let key = newest(&entry);
        if let Some(old) = self.by_name.insert(entry.run.name.clone(), key.clone()) {
            self.entries.remove(&old);
        }
        self.entries.insert(key, entry);
    }

    pub(super) fn remove(&mut self, name: &RecordingName) {
        if let Some(key) = self.by_name.remove(name) {
            self.entries.remove(&key);
        }
    }

    pub(super) fn get(&self, name: &RecordingName) -> Option<&CatalogueEntry> {
        self.entries.get(self.by_name.get(name)?)
    }

    /// Newest first.
    pub(super) fn iter(&self) -> impl Iterator<Item = &CatalogueEntry> {
        self.entries.values()
    }
}
