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
pub use summary::{LabRow, NetsReport, RuleVerdict};

/// The access design's folder, beside the labs'.
pub(crate) const ACCESS: &str = "access";

/// Events no controller may forbid, whatever a lab's file says: a person
/// can always stop the robot (the emergency stop obeys no net at all).
const NEVER_FORBIDDEN: &[&str] = &["stop"];

/// One lab's charts and controllers, as written.
#[derive(Debug, Clone)]
pub struct LabDesign {
    /// Its folder: a lab's id, or [`ACCESS`].
    pub lab: &'static str,
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
    #[error("cannot write {path}: {why}")]
    Write { path: String, why: String },
    #[error("{path}: {why}")]
    LabFile { path: String, why: String },
    #[error("{lab}: chart '{chart}': {why}")]
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

impl LabDesign {
    /// Every lab's design as shipped.
    pub fn shipped() -> Result<Vec<LabDesign>, DesignError> {
        let read = |path: &str| {
            SHIPPED
                .iter()
                .find(|(p, _)| *p == path)
                .map(|(_, text)| (*text).to_owned())
                .ok_or_else(|| DesignError::Read {
                    path: path.to_owned(),
                    why: "not among the shipped charts".to_owned(),
                })
        };
        designs()
            .map(|lab| LabDesign::from_files(lab, &read))
            .collect()
    }

    /// Every lab's design from the charts folder `dir` (laid out as
    /// `crates/vl-core/nets/`).
    pub fn load(dir: &Path) -> Result<Vec<LabDesign>, DesignError> {
        let read = |path: &str| {
            let file = dir.join(path);
            std::fs::read_to_string(&file).map_err(|e| DesignError::Read {
                path: file.display().to_string(),
                why: e.to_string(),
            })
        };
        designs()
            .map(|lab| LabDesign::from_files(lab, &read))
            .collect()
    }

    fn from_files(
        lab: &'static str,
        read: &dyn Fn(&str) -> Result<String, DesignError>,
    ) -> Result<LabDesign, DesignError> {
        let path = format!("{lab}/lab.toml");
        let file: LabFile = toml::from_str(&read(&path)?).map_err(|e| DesignError::LabFile {
            path: path.clone(),
            why: e.to_string(),
        })?;
        let charts = file
            .charts
            .iter()
            .map(|name| {
                let own = read(&format!("{lab}/{name}.scxml"));
                let text = own.or_else(|_| read(&format!("common/{name}.scxml")))?;
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
            lab,
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
