//! The labs designed by their own nets (thesis ch. 4–6): each lab's
//! functionalities are statecharts (`crates/vl-core/nets/`), turned into
//! nets, composed by their shared events, given controllers, and analysed;
//! the controlled net is what the Host's supervisor runs.
//!
//! A lab's design is a `lab.toml` naming its charts (looked up in the lab's
//! folder, then in `common/`), the events that happen by themselves
//! (uncontrollable), and its controllers, each a rule with the reason for
//! it. Rules are `vl petri control` constraints whose transition may also
//! be an event: `if execute.running then not define` forbids every
//! transition labelled `define` while `execute.running` is marked, and
//! `grant@access.waiting` names those labelled `grant` that take from
//! `access.waiting`.
//!
//! Beside the labs is the access design (`access/lab.toml`): who watches,
//! waits and drives, composed with mount, define and execute. Its chart is
//! everyone's at once (`[people]` puts one token per person in its initial
//! state), and the Host runs its controlled net beside the mounted lab's.

mod pipeline;
mod report;
mod summary;

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use thiserror::Error;

use crate::{Experiment, Named};

pub use pipeline::{Designed, Interleaving, design};
pub use summary::{CheckReport, FolderCheck, LabRow, NetsReport, RuleVerdict};

/// The access design's folder, beside the labs'.
pub(crate) const ACCESS: &str = "access";

/// Events no controller may forbid, whatever a lab's file says: a person
/// can always stop the robot (the emergency stop obeys no net at all).
const NEVER_FORBIDDEN: &[&str] = &["stop"];

/// One lab's charts and controllers, as written.
#[derive(Debug, Clone)]
pub struct LabDesign {
    /// Its folder's name: a lab's id, or [`ACCESS`].
    pub lab: String,
    /// Where it was read from, as messages name it.
    pub source: String,
    pub title: String,
    /// Each chart's name and SCXML text, in composition order.
    pub charts: Vec<(String, String)>,
    /// Charts that are several people's at once, and how many: the chart's
    /// initial state holds one token per person.
    pub people: BTreeMap<String, u32>,
    /// Events a controller may not forbid.
    pub uncontrollable: Vec<String>,
    pub controllers: Vec<Rule>,
}

/// A controller: the rule it enforces and why the lab needs it.
#[derive(Debug, Clone, Deserialize)]
pub struct Rule {
    pub why: String,
    pub rule: String,
}

/// An experiment folder's file of its design (beside its charts).
pub(crate) const EXPERIMENT_FILE: &str = "experiment.toml";

/// The most bytes a design's file or chart may have: the shipped ones
/// have a few kilobytes.
pub(crate) const MAX_FILE_BYTES: u64 = 256 * 1024;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LabFile {
    title: String,
    charts: Vec<String>,
    #[serde(default)]
    uncontrollable: Vec<String>,
    #[serde(default)]
    people: BTreeMap<String, u32>,
    #[serde(default, rename = "controller")]
    controllers: Vec<Rule>,
}

#[derive(Debug, Error)]
pub enum DesignError {
    #[error("cannot read {path}: {why}")]
    Read { path: String, why: String },
    #[error("{path}: no such file")]
    Missing { path: String },
    #[error("cannot write {path}: {why}")]
    Write { path: String, why: String },
    #[error("{path}: {why}")]
    LabFile { path: String, why: String },
    #[error("{lab}/{chart}.scxml: {why}")]
    Chart {
        lab: String,
        chart: String,
        why: String,
    },
    #[error("{lab}: composing the charts: {why}")]
    Compose { lab: String, why: String },
    #[error("{lab}: controller '{rule}': {why}")]
    Controller {
        lab: String,
        rule: String,
        why: String,
    },
    #[error("{path}: {why}")]
    Folder { path: String, why: String },
    #[error("{lab}: uncontrollable event '{event}' is no chart's")]
    UnknownEvent { lab: String, event: String },
    #[error("{lab}: exploring the {which} net: {why}")]
    Explore {
        lab: String,
        which: &'static str,
        why: String,
    },
}

/// The shipped charts and lab files, built in so `vl lab nets` runs from
/// any directory.
const SHIPPED: &[(&str, &str)] = &[
    (
        "common/mount.scxml",
        include_str!("../../nets/common/mount.scxml"),
    ),
    (
        "common/define.scxml",
        include_str!("../../nets/common/define.scxml"),
    ),
    (
        "common/execute.scxml",
        include_str!("../../nets/common/execute.scxml"),
    ),
    (
        "common/cspace.scxml",
        include_str!("../../nets/common/cspace.scxml"),
    ),
    (
        "common/access.scxml",
        include_str!("../../nets/common/access.scxml"),
    ),
    (
        "access/lab.toml",
        include_str!("../../nets/access/lab.toml"),
    ),
    (
        "navigation/lab.toml",
        include_str!("../../nets/navigation/lab.toml"),
    ),
    (
        "navigation/planning.scxml",
        include_str!("../../nets/navigation/planning.scxml"),
    ),
    (
        "navigation/forecast.scxml",
        include_str!("../../nets/navigation/forecast.scxml"),
    ),
    (
        "navigation/following.scxml",
        include_str!("../../nets/navigation/following.scxml"),
    ),
    (
        "teleoperation/lab.toml",
        include_str!("../../nets/teleoperation/lab.toml"),
    ),
    (
        "teleoperation/field.scxml",
        include_str!("../../nets/teleoperation/field.scxml"),
    ),
    (
        "teleoperation/teleoperation.scxml",
        include_str!("../../nets/teleoperation/teleoperation.scxml"),
    ),
];

/// A shipped file by its path in `crates/vl-core/nets/`.
fn shipped(path: &str) -> Result<String, DesignError> {
    SHIPPED
        .iter()
        .find(|(p, _)| *p == path)
        .map(|(_, text)| (*text).to_owned())
        .ok_or_else(|| DesignError::Missing {
            path: path.to_owned(),
        })
}

/// The shared charts' names, which any lab may compose with its own.
fn shared_charts() -> Vec<&'static str> {
    SHIPPED
        .iter()
        .filter_map(|(p, _)| p.strip_prefix("common/")?.strip_suffix(".scxml"))
        .collect()
}

/// Whether `id` may name an experiment: what URLs, recordings and
/// commands carry it as (a lowercase word, `-` and `_` allowed), and not a
/// folder the shipped designs keep for themselves.
fn checked_id(id: &str) -> Result<(), String> {
    let word = id.len() <= 32
        && id.starts_with(|c: char| c.is_ascii_lowercase())
        && id
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_');
    if !word {
        return Err(format!(
            "'{id}' is no experiment id: a lowercase word of at most 32 letters, digits, '-' or '_', starting with a letter"
        ));
    }
    if id == ACCESS || id == "common" {
        return Err(format!(
            "'{id}' is the shipped {id} charts' folder, no experiment's"
        ));
    }
    Ok(())
}

/// A file's text, refused unread when larger than [`MAX_FILE_BYTES`].
fn read_bounded(file: &Path) -> Result<String, DesignError> {
    use std::io::Read;
    let failed = |why: String| DesignError::Read {
        path: file.display().to_string(),
        why,
    };
    let opened = std::fs::File::open(file).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => DesignError::Missing {
            path: file.display().to_string(),
        },
        _ => failed(e.to_string()),
    })?;
    let mut bytes = Vec::new();
    opened
        .take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| failed(e.to_string()))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(failed(format!(
            "larger than the {} KiB a design's file may have",
            MAX_FILE_BYTES / 1024
        )));
    }
    String::from_utf8(bytes).map_err(|_| failed("is not UTF-8 text".to_owned()))
}

impl LabDesign {
    /// Every lab's design as shipped.
    pub fn shipped() -> Result<Vec<LabDesign>, DesignError> {
        designs()
            .map(|lab| {
                let source = format!("crates/vl-core/nets/{lab}");
                LabDesign::from_files(lab, &format!("{lab}/lab.toml"), &source, &shipped)
            })
            .collect()
    }

    /// Every lab's design from the charts folder `dir` (laid out as
    /// `crates/vl-core/nets/`).
    pub fn load(dir: &Path) -> Result<Vec<LabDesign>, DesignError> {
        let read = |path: &str| read_bounded(&dir.join(path));
        designs()
            .map(|lab| {
                let source = dir.join(lab).display().to_string();
                LabDesign::from_files(lab, &format!("{lab}/lab.toml"), &source, &read)
            })
            .collect()
    }

    /// An experiment folder's design: its `experiment.toml`, its charts
    /// beside it or else among the shipped shared ones (`common/`). Every
    /// file is read only up to [`MAX_FILE_BYTES`]; the folder's name is the
    /// experiment's id.
    pub fn from_folder(dir: &Path) -> Result<LabDesign, DesignError> {
        let folder = |why: String| DesignError::Folder {
            path: dir.display().to_string(),
            why,
        };
        let lab = dir
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| folder("is no folder with a name".to_owned()))?;
        checked_id(lab).map_err(folder)?;
        if !dir.join(EXPERIMENT_FILE).is_file() {
            return Err(folder(format!("has no {EXPERIMENT_FILE}")));
        }
        let read = |path: &str| match path.strip_prefix(&format!("{lab}/")) {
            Some(own) => read_bounded(&dir.join(own)),
            None => shipped(path),
        };
        let source = dir.display().to_string();
        LabDesign::from_files(lab, &format!("{lab}/{EXPERIMENT_FILE}"), &source, &read)
    }

    /// The files of a new experiment folder `id`: the mobile-robotics lab's
    /// own charts and its `experiment.toml`, retitled, to change from there.
    /// It passes `vl lab check` as it is.
    pub fn scaffold(id: &str) -> Result<Vec<(String, String)>, DesignError> {
        checked_id(id).map_err(|why| DesignError::Folder {
            path: id.to_owned(),
            why,
        })?;
        let from = Experiment::Navigation.id();
        let mut files = Vec::new();
        for (path, text) in SHIPPED {
            let Some(name) = path.strip_prefix(&format!("{from}/")) else {
                continue;
            };
            if name == "lab.toml" {
                let retitled: String = text
                    .lines()
                    .map(|line| match line.starts_with("title = ") {
                        true => format!("title = \"{id}: plan a path and follow it\"\n"),
                        false => format!("{line}\n"),
                    })
                    .collect();
                let header = format!(
                    "# The experiment `{id}`, made by `vl lab new` from the mobile-robotics lab:\n\
                     # change its charts and controllers, then `vl lab check` this folder.\n"
                );
                files.push((EXPERIMENT_FILE.to_owned(), header + &retitled));
            } else {
                files.push((name.to_owned(), (*text).to_owned()));
            }
        }
        Ok(files)
    }

    /// The design in `path` (`LAB/FILE`, as `read` takes it), from the
    /// folder `source` names in messages.
    fn from_files(
        lab: &str,
        path: &str,
        source: &str,
        read: &dyn Fn(&str) -> Result<String, DesignError>,
    ) -> Result<LabDesign, DesignError> {
        let shown = format!("{source}/{}", path.rsplit('/').next().unwrap_or(path));
        let file: LabFile = toml::from_str(&read(path)?).map_err(|e| DesignError::LabFile {
            path: shown.clone(),
            why: e.to_string(),
        })?;
        let charts = file
            .charts
            .iter()
            .map(|name| {
                let text = match read(&format!("{lab}/{name}.scxml")) {
                    Err(DesignError::Missing { .. }) => read(&format!("common/{name}.scxml")),
                    own => own,
                }
                .map_err(|e| match e {
                    DesignError::Missing { .. } => DesignError::LabFile {
                        path: shown.clone(),
                        why: format!(
                            "chart '{name}': no {name}.scxml beside it, nor among the shared charts ({})",
                            shared_charts().join(", ")
                        ),
                    },
                    other => other,
                })?;
                Ok((name.clone(), text))
            })
            .collect::<Result<_, DesignError>>()?;
        let mut uncontrollable = file.uncontrollable;
        for event in NEVER_FORBIDDEN {
            if !uncontrollable.iter().any(|e| e == event) {
                uncontrollable.push((*event).to_owned());
            }
        }
        Ok(LabDesign {
            lab: lab.to_owned(),
            source: source.to_owned(),
            title: file.title,
            charts,
            uncontrollable,
            people: file.people,
            controllers: file.controllers,
        })
    }
}

/// Each design's folder: the labs', then access.
fn designs() -> impl Iterator<Item = &'static str> {
    Experiment::ALL
        .iter()
        .map(|lab| lab.id())
        .chain(std::iter::once(ACCESS))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_labs_design_sound_nets() {
        for lab in LabDesign::shipped().unwrap() {
            let designed = design(&lab).unwrap();
            for (name, text) in designed.files() {
                if name == "report.md" {
                    println!("{text}");
                }
            }
            assert!(designed.sound(), "{}", lab.lab);
        }
    }

    #[test]
    fn no_rule_may_forbid_a_stop() {
        let mut lab = LabDesign::shipped()
            .unwrap()
            .into_iter()
            .find(|l| l.lab == "teleoperation")
            .unwrap();
        lab.controllers.push(Rule {
            why: "a careless rule".to_owned(),
            rule: "if execute.running then not stop".to_owned(),
        });
        let Err(e) = design(&lab) else {
            panic!("a rule forbidding a stop was taken");
        };
        let e = e.to_string();
        assert!(
            e.contains("_stop' is uncontrollable, so nothing may disable it"),
            "{e}"
        );
    }
}
