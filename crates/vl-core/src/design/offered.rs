//! The experiments a lab offers, each designed and verified: what the
//! Host serves, the Guest follows and the tools run, looked up by id.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use vl_petri::Net;

use super::{Declared, DesignError, LabDesign, design};
use crate::{Experiment, ExperimentId};

/// An experiment on offer: as declared, with the controlled net its design
/// gives (what the supervisor runs).
#[derive(Debug, Clone)]
pub struct Offered {
    pub declared: Declared,
    pub net: Net,
}

impl Offered {
    pub fn experiment(&self) -> &Experiment {
        &self.declared.experiment
    }
}

/// The experiments a lab offers, in the order they are listed.
#[derive(Debug, Clone)]
pub struct Experiments {
    offered: Vec<Arc<Offered>>,
}

/// An id that names no experiment on offer, with those that do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown experiment '{name}'{renamed} (known: {known})",
    renamed = now.as_ref().map(|n| format!(": it is called '{n}' now")).unwrap_or_default(),
    known = known.join(", "))]
pub struct UnknownExperiment {
    pub name: String,
    pub known: Vec<String>,
    /// The id of what `name` once named.
    pub now: Option<String>,
}

impl Experiments {
    /// The experiments vl ships, designed once per process.
    pub fn shipped() -> &'static Experiments {
        static SHIPPED: OnceLock<Experiments> = OnceLock::new();
        SHIPPED.get_or_init(|| {
            let designs =
                LabDesign::shipped().expect("the shipped designs are built in and tested");
            Experiments::of(designs).expect("the shipped designs are sound, as tested")
        })
    }

    /// The experiments among `designs` (access is not one), each designed
    /// and verified: the first that is not sound is refused with its
    /// findings.
    pub fn of(designs: Vec<LabDesign>) -> Result<Experiments, DesignError> {
        let mut offered = Vec::new();
        for lab in designs {
            let Some(declared) = lab.experiment.clone() else {
                continue;
            };
            let designed = design(&lab)?;
            let findings = designed.findings();
            if !findings.is_empty() {
                return Err(DesignError::Unsound {
                    lab: lab.source.clone(),
                    findings,
                });
            }
            offered.push(Arc::new(Offered {
                declared,
                net: designed.controlled,
            }));
        }
        Ok(Experiments { offered })
    }

    /// These experiments and those of `folders`, after them: a folder
    /// with an `experiment.toml` is one experiment, any other holds
    /// experiment folders. Each is designed and verified; the first that
    /// fails is refused, as is an id two experiments share — nothing is
    /// half-loaded.
    pub fn with_folders(&self, folders: &[PathBuf]) -> Result<Experiments, DesignError> {
        let mut designs = Vec::new();
        for folder in folders {
            for one in experiment_folders(folder)? {
                designs.push(LabDesign::from_folder(&one)?);
            }
        }
        let mut offered = self.offered.clone();
        for added in Experiments::of(designs)?.offered {
            let id = &added.experiment().id;
            if let Some(first) = offered.iter().find(|o| o.experiment().id == *id) {
                return Err(DesignError::Folder {
                    path: added.declared.source.clone(),
                    why: format!(
                        "its id '{id}' is taken by the experiment of {}: rename its folder",
                        first.declared.source
                    ),
                });
            }
            offered.push(added);
        }
        Ok(Experiments { offered })
    }

    /// The experiments, in order.
    pub fn experiments(&self) -> impl Iterator<Item = &Experiment> {
        self.offered.iter().map(|o| o.experiment())
    }

    /// Their ids, in order.
    pub fn ids(&self) -> Vec<ExperimentId> {
        self.experiments().map(|e| e.id.clone()).collect()
    }

    /// The experiment with id `id`.
    pub fn get(&self, id: &str) -> Result<&Arc<Offered>, UnknownExperiment> {
        self.offered
            .iter()
            .find(|o| o.experiment().id == *id)
            .ok_or_else(|| UnknownExperiment {
                name: id.chars().take(64).collect(),
                known: self.experiments().map(|e| e.id.to_string()).collect(),
                now: self
                    .offered
                    .iter()
                    .find(|o| o.declared.formerly.iter().any(|f| f == id))
                    .map(|o| o.experiment().id.to_string()),
            })
    }

    /// Only the experiments `ids` names, in its order.
    pub fn only(&self, ids: &[ExperimentId]) -> Result<Experiments, UnknownExperiment> {
        let offered = ids
            .iter()
            .map(|id| self.get(id.as_str()).cloned())
            .collect::<Result<_, _>>()?;
        Ok(Experiments { offered })
    }

    /// Each experiment's id and controlled net, for a supervisor.
    pub fn nets(&self) -> Vec<(ExperimentId, Net)> {
        self.offered
            .iter()
            .map(|o| (o.experiment().id.clone(), o.net.clone()))
            .collect()
    }
}

/// The experiment folders `folder` is or holds, in name order.
fn experiment_folders(folder: &Path) -> Result<Vec<PathBuf>, DesignError> {
    if folder.join(super::EXPERIMENT_FILE).is_file() {
        return Ok(vec![folder.to_path_buf()]);
    }
    let unreadable = |e: std::io::Error| DesignError::Read {
        path: folder.display().to_string(),
        why: e.to_string(),
    };
    let mut found: Vec<PathBuf> = std::fs::read_dir(folder)
        .map_err(unreadable)?
        .filter_map(|entry| Some(entry.ok()?.path()))
        .filter(|path| path.join(super::EXPERIMENT_FILE).is_file())
        .collect();
    found.sort();
    if found.is_empty() {
        return Err(DesignError::Folder {
            path: folder.display().to_string(),
            why: format!(
                "has no {} and no folder in it has one",
                super::EXPERIMENT_FILE
            ),
        });
    }
    Ok(found)
}
