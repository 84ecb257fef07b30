//! The labs designed by their own nets (thesis ch. 4–6): each experiment
//! is a folder (the shipped ones in `assets/experiments/`) whose
//! functionalities are statecharts, turned into nets, composed by their
//! shared events with the shared charts (`crates/vl-core/nets/common/`),
//! given controllers, and analysed; the controlled net is what the Host's
//! supervisor runs.
//!
//! An experiment's design is its `experiment.toml`: what it is (title,
//! help, what the user defines, the run's components, success, rubric; an
//! [`Experiment`]), the charts it is made of (looked up in its folder, then
//! in `common/`), the events that happen by themselves (uncontrollable),
//! and its controllers, each a rule with the reason for it. Rules are `vl petri control` constraints whose transition may also
//! be an event: `if execute.running then not define` forbids every
//! transition labelled `define` while `execute.running` is marked, and
//! `grant@access.waiting` names those labelled `grant` that take from
//! `access.waiting`.
//!
//! Beside the labs is the access design (`crates/vl-core/nets/access/lab.toml`): who watches,
//! waits and drives, composed with mount, define and execute. Its chart is
//! everyone's at once (`[people]` puts one token per person in its initial
//! state), and the Host runs its controlled net beside the mounted lab's.

mod offered;
mod pipeline;
mod report;
mod summary;

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use thiserror::Error;

use crate::{DefineKind, Experiment, ExperimentId, Rubric, RunPlan, Success};

pub use offered::{Experiments, Offered, UnknownExperiment};
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
    /// What the folder declares the experiment to be; none for access.
    pub experiment: Option<Declared>,
}

/// An experiment as its folder declares it, with what only the lab uses.
#[derive(Debug, Clone)]
pub struct Declared {
    pub experiment: Experiment,
    /// The ids it once had: refused, naming it.
    pub formerly: Vec<String>,
    /// How its runs are graded, unless the lab's config says otherwise.
    pub rubric: Option<Rubric>,
    /// Where it was read from, as messages name it.
    pub source: String,
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
    #[serde(default)]
    help: String,
    #[serde(default)]
    formerly: Vec<String>,
    charts: Vec<String>,
    #[serde(default)]
    define: Vec<DefineKind>,
    run: Option<RunPlan>,
    #[serde(default)]
    success: Success,
    rubric: Option<Rubric>,
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
    #[error("{lab}: {why}")]
    Component { lab: String, why: String },
    #[error("{lab}: not sound: {}", findings.join("; "))]
    Unsound { lab: String, findings: Vec<String> },
    #[error("{lab}: uncontrollable event '{event}' is no chart's")]
    UnknownEvent { lab: String, event: String },
    #[error("{lab}: exploring the {which} net: {why}")]
    Explore {
        lab: String,
        which: &'static str,
        why: String,
    },
}

/// The shipped shared charts, access design and experiment folders (by
/// their path in `crates/vl-core/nets/` or `assets/experiments/`), built in
/// so `vl` runs from any directory.
const SHIPPED: &[(&str, &str)] = include!(concat!(env!("OUT_DIR"), "/shipped.rs"));

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

/// Whether `id` may name an experiment: a word ([`ExperimentId`]), and
/// not a folder the shipped designs keep for themselves.
fn checked_id(id: &str) -> Result<ExperimentId, String> {
    let id = ExperimentId::new(id).map_err(|e| e.to_string())?;
    if id == *ACCESS || id == *"common" {
        return Err(format!(
            "'{id}' is the shipped {id} charts' folder, no experiment's"
        ));
    }
    Ok(id)
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
    /// Every shipped design: the experiments', then access.
    pub fn shipped() -> Result<Vec<LabDesign>, DesignError> {
        designs(shipped_experiments())
            .map(|(lab, file)| {
                let source = match file {
                    EXPERIMENT_FILE => format!("assets/experiments/{lab}"),
                    _ => format!("crates/vl-core/nets/{lab}"),
                };
                LabDesign::from_files(lab, &format!("{lab}/{file}"), &source, &shipped)
            })
            .collect()
    }

    /// Every design in `dir`: each folder with an `experiment.toml`, then
    /// `access/lab.toml`; charts not in a folder are the shared ones of
    /// `dir/common/`. The shared charts and the access design not in `dir`
    /// are the shipped ones.
    pub fn load(dir: &Path) -> Result<Vec<LabDesign>, DesignError> {
        let shared = |path: &str| path.starts_with("common/") || path.starts_with("access/");
        let read = |path: &str| match read_bounded(&dir.join(path)) {
            Err(DesignError::Missing { .. }) if shared(path) => shipped(path),
            read => read,
        };
        let mut ids: Vec<String> = std::fs::read_dir(dir)
            .map_err(|e| DesignError::Read {
                path: dir.display().to_string(),
                why: e.to_string(),
            })?
            .filter_map(|entry| {
                let entry = entry.ok()?;
                entry.path().join(EXPERIMENT_FILE).is_file().then_some(())?;
                entry.file_name().into_string().ok()
            })
            .collect();
        ids.sort();
        designs(ids.iter().map(String::as_str))
            .map(|(lab, file)| {
                let source = dir.join(lab).display().to_string();
                LabDesign::from_files(lab, &format!("{lab}/{file}"), &source, &read)
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

    /// The files of a new experiment folder `id`: the first shipped
    /// experiment's charts and its `experiment.toml`, retitled, to change
    /// from there. It passes `vl lab check` as it is.
    pub fn scaffold(id: &str) -> Result<Vec<(String, String)>, DesignError> {
        checked_id(id).map_err(|why| DesignError::Folder {
            path: id.to_owned(),
            why,
        })?;
        let from = shipped_experiments().next().expect("vl ships experiments");
        let mut files = Vec::new();
        for (path, text) in SHIPPED {
            let Some(name) = path.strip_prefix(&format!("{from}/")) else {
                continue;
            };
            if name == EXPERIMENT_FILE {
                // Retitled, without the ids it once had, and graded by the
                // default rubric until it says otherwise.
                let mut in_rubric = false;
                let retitled: String = text
                    .lines()
                    .filter(|line| {
                        in_rubric = match in_rubric {
                            true => !line.is_empty(),
                            false => *line == "[rubric]",
                        };
                        !in_rubric && !line.starts_with("formerly = ")
                    })
                    .map(|line| match line.strip_prefix("title = \"") {
                        Some(title) => format!("title = \"{id}: {title}\n"),
                        None => format!("{line}\n"),
                    })
                    .collect();
                let header = format!(
                    "# The experiment `{id}`, made by `vl lab new` from the experiment `{from}`:\n\
                     # change its charts, controllers and rubric, then `vl lab check` this folder.\n"
                );
                files.push((EXPERIMENT_FILE.to_owned(), header + &retitled));
            } else {
                files.push((name.to_owned(), (*text).to_owned()));
            }
        }
        Ok(files)
    }

    /// The design in `path` (`LAB/FILE`, as `read` takes it), from the
    /// folder `source` names in messages. An `experiment.toml` declares an
    /// experiment: its run and definition are checked here.
    fn from_files(
        lab: &str,
        path: &str,
        source: &str,
        read: &dyn Fn(&str) -> Result<String, DesignError>,
    ) -> Result<LabDesign, DesignError> {
        let file_name = path.rsplit('/').next().unwrap_or(path);
        let shown = format!("{source}/{file_name}");
        let bad = |why: String| DesignError::LabFile {
            path: shown.clone(),
            why,
        };
        let file: LabFile = toml::from_str(&read(path)?).map_err(|e| bad(e.to_string()))?;
        let charts = file
            .charts
            .iter()
            .map(|name| {
                let text = match read(&format!("{lab}/{name}.scxml")) {
                    Err(DesignError::Missing { .. }) => read(&format!("common/{name}.scxml")),
                    own => own,
                }
                .map_err(|e| match e {
                    DesignError::Missing { .. } => bad(format!(
                        "chart '{name}': no {name}.scxml beside it, nor among the shared charts ({})",
                        shared_charts().join(", ")
                    )),
                    other => other,
                })?;
                Ok((name.clone(), text))
            })
            .collect::<Result<_, DesignError>>()?;
        let experiment = match (file_name, file.run) {
            (EXPERIMENT_FILE, None) => {
                return Err(bad(
                    "no [run]: say which of vl's components a run is made of".to_owned(),
                ));
            }
            (EXPERIMENT_FILE, Some(run)) => {
                let id = checked_id(lab).map_err(&bad)?;
                let rubric = file
                    .rubric
                    .map(Rubric::checked)
                    .transpose()
                    .map_err(|e| bad(e.to_string()))?;
                let experiment = Experiment {
                    id,
                    title: file.title.clone(),
                    help: file.help,
                    define: file.define,
                    run,
                    success: file.success,
                };
                experiment.check().map_err(|e| bad(e.to_string()))?;
                Some(Declared {
                    experiment,
                    formerly: file.formerly,
                    rubric,
                    source: source.to_owned(),
                })
            }
            (_, _) => None,
        };
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
            experiment,
        })
    }
}

/// The shipped experiments' ids, in the order they are listed.
fn shipped_experiments() -> impl Iterator<Item = &'static str> {
    SHIPPED
        .iter()
        .filter_map(|(p, _)| p.strip_suffix(&format!("/{EXPERIMENT_FILE}")))
}

/// Each design's folder and file: the experiments', then access.
fn designs<'a>(
    experiments: impl Iterator<Item = &'a str>,
) -> impl Iterator<Item = (&'a str, &'static str)> {
    experiments
        .map(|lab| (lab, EXPERIMENT_FILE))
        .chain(std::iter::once((ACCESS, "lab.toml")))
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
