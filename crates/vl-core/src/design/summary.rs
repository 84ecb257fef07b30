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
    pub lab: String,
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
                l.lab.clone(),
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
            let dir = self.out.join(&l.lab);
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

/// `vl lab check`: each experiment folder, designed and verified, or
/// refused.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct CheckReport {
    pub folders: Vec<FolderCheck>,
}

/// One folder's verdict.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct FolderCheck {
    pub folder: PathBuf,
    /// Its id and title, once its files were read.
    pub id: Option<String>,
    pub title: Option<String>,
    pub charts: usize,
    pub rules: usize,
    /// Reachable markings of its controlled net.
    pub markings: usize,
    /// Why it could not be designed at all (a file, a chart, a rule).
    pub refused: Option<String>,
    /// What keeps its controlled net from being a lab's, each with the
    /// firing sequence that shows it.
    pub findings: Vec<String>,
}

impl FolderCheck {
    pub fn passed(&self) -> bool {
        self.refused.is_none() && self.findings.is_empty()
    }

    /// The verdict on `folder`, whatever became of it.
    pub fn of(folder: &Path) -> FolderCheck {
        let mut check = FolderCheck {
            folder: folder.to_path_buf(),
            id: None,
            title: None,
            charts: 0,
            rules: 0,
            markings: 0,
            refused: None,
            findings: Vec::new(),
        };
        let designed = super::LabDesign::from_folder(folder).and_then(|lab| {
            check.id = Some(lab.lab.clone());
            check.title = Some(lab.title.clone());
            check.charts = lab.charts.len();
            check.rules = lab.controllers.len();
            super::design(&lab)
        });
        match designed {
            Ok(designed) => {
                check.markings = designed.controlled_analysis.states;
                check.findings = designed.findings();
            }
            Err(e) => check.refused = Some(e.to_string()),
        }
        check
    }
}

impl Report for CheckReport {
    fn table(&self) -> Table {
        let mut table = Table::columns(&["folder", "id", "charts", "rules", "markings", "verdict"]);
        for f in &self.folders {
            table.row(vec![
                f.folder.display().to_string(),
                f.id.clone().unwrap_or_default(),
                f.charts.to_string(),
                f.rules.to_string(),
                f.markings.to_string(),
                match (&f.refused, f.findings.len()) {
                    (Some(_), _) => "refused".to_owned(),
                    (None, 0) => "passes".to_owned(),
                    (None, n) => format!("fails ({n})"),
                },
            ]);
        }
        let mut table = table.title(
            "each experiment folder's charts through the pipeline: composed with the shared \
             charts, given its controllers, and verified (bounded, safe, no dead end, a way \
             back to the start from everywhere, every rule kept):",
        );
        for f in &self.folders {
            let name =
                f.id.clone()
                    .unwrap_or_else(|| f.folder.display().to_string());
            if let Some(why) = &f.refused {
                table = table.note(format!("{name}: refused: {why}"));
            }
            for finding in &f.findings {
                table = table.note(format!("{name}: {finding}"));
            }
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
            lab: self.design.lab.clone(),
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
