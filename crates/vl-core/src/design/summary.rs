//! A lab's outcome as `vl lab nets` prints it: the controlled net's
//! properties and the rules broken without and with its controllers.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::Rule;
use super::pipeline::{Designed, Interleaving};
use vl_report::table::{Report, Table};

/// One lab's outcome, as the table and `--json` show it.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct LabRow {
    pub lab: &'static str,
    pub charts: usize,
    /// Rules the uncontrolled composition can break.
    pub broken_without: usize,
    pub rules: usize,
    pub places: usize,
    pub transitions: usize,
    pub markings: usize,
    pub bounded: bool,
    pub safe: bool,
    /// Whether a chart is several people's, so its places hold more than
    /// one token by design and the net need not be safe.
    pub crowd: bool,
    pub live: bool,
    pub reversible: bool,
    pub deadlock_free: bool,
    /// Rules the controlled net can still break.
    pub broken_with: usize,
    /// Files written, or (with --check) found different.
    pub files: Vec<String>,
    /// Each rule: why, how the uncontrolled net breaks it, whether the
    /// controlled one still can.
    pub verdicts: Vec<RuleVerdict>,
}

/// One rule of a lab, without and with its controllers.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct RuleVerdict {
    pub why: String,
    /// The events of the shortest sequence breaking it without the
    /// controllers; none if it cannot be broken even then.
    pub broken_by: Option<Vec<String>>,
    pub holds: bool,
}

/// Every lab's outcome, and where its files are.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct NetsReport {
    pub out: PathBuf,
    pub check: bool,
    pub pictures: bool,
    pub labs: Vec<LabRow>,
}

impl Report for NetsReport {
    fn table(&self) -> Table {
        let yes = |b: bool| if b { "yes" } else { "NO" }.to_owned();
        let mut table = Table::columns(&[
            "lab",
            "charts",
            "broken without",
            "places",
            "transitions",
            "markings",
            "bounded",
            "safe",
            "live",
            "reversible",
            "deadlock-free",
            "broken with",
        ]);
        for l in &self.labs {
            table.row(vec![
                l.lab.to_owned(),
                l.charts.to_string(),
                format!("{} of {}", l.broken_without, l.rules),
                l.places.to_string(),
                l.transitions.to_string(),
                l.markings.to_string(),
                yes(l.bounded),
                match (l.safe, l.crowd) {
                    (false, true) => "no (people)".to_owned(),
                    (safe, _) => yes(safe),
                },
                yes(l.live),
                yes(l.reversible),
                yes(l.deadlock_free),
                format!("{} of {}", l.broken_with, l.rules),
            ]);
        }
        let mut table = table.title(
            "each lab's controlled net, and the rules broken without and with its controllers:",
        );
        for l in &self.labs {
            for v in &l.verdicts {
                table = table.note(format!(
                    "{}: {}: {}; {}",
                    l.lab,
                    v.why,
                    match &v.broken_by {
                        Some(events) => format!("without controllers {}", events.join(" → ")),
                        None => "holds without controllers".to_owned(),
                    },
                    if v.holds {
                        "holds with them"
                    } else {
                        "BROKEN with them"
                    }
                ));
            }
        }
        for l in &self.labs {
            let dir = self.out.join(l.lab);
            table = table.note(if self.check {
                match l.files.is_empty() {
                    true => format!("{}: up to date", dir.display()),
                    false => format!("{}: differs in {}", dir.display(), l.files.join(", ")),
                }
            } else {
                format!("{}: wrote {}", dir.display(), l.files.join(", "))
            });
        }
        if !self.check && !self.pictures {
            table = table.note("Graphviz's `dot` is not installed: no SVG pictures");
        }
        table
    }
}

impl Designed {
    /// The lab's outcome, with the `files` written (or found different).
    pub fn summary(&self, files: Vec<String>) -> LabRow {
        let a = &self.controlled_analysis;
        let count =
            |v: &[(Rule, Option<Interleaving>)]| v.iter().filter(|(_, bad)| bad.is_some()).count();
        LabRow {
            lab: self.design.lab,
            charts: self.design.charts.len(),
            broken_without: count(&self.bad),
            rules: self.bad.len(),
            places: a.places,
            transitions: a.transitions,
            markings: a.states,
            bounded: a.bounded,
            safe: a.safe,
            crowd: !self.design.people.is_empty(),
            live: a.live,
            reversible: a.reversible,
            deadlock_free: !a.deadlock,
            broken_with: count(&self.still_bad),
            files,
            verdicts: self
                .bad
                .iter()
                .zip(&self.still_bad)
                .map(|((rule, bad), (_, still))| RuleVerdict {
                    why: rule.why.clone(),
                    broken_by: bad.as_ref().map(|b| b.events.clone()),
                    holds: still.is_none(),
                })
                .collect(),
        }
    }

    /// The lab's files that are missing from `dir` or differ from what the
    /// pipeline makes now.
    pub fn differing(&self, dir: &Path) -> Vec<String> {
        self.files()
            .into_iter()
            .filter(|(name, text)| {
                std::fs::read_to_string(dir.join(name)).ok().as_ref() != Some(text)
            })
            .map(|(name, _)| name)
            .collect()
    }
}
