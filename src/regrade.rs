//! `vl record regrade`: a recorded run graded again by its experiment's
//! rubric and, when a user's controller drove it, exactly that module (the
//! recording's copy, checked against the hash the run was defined with)
//! run again on the lab's twin from where the run began, each seed graded
//! alike — so a teacher can re-mark a run, and see whether the student's
//! code does what the run showed, without the robot.

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::Serialize;
use vl_core::{Experiments, ForecastLimits, ForecastVerdict, Grade, Pose, Rubric, Summary};
use vl_record::Recording;
use vl_report::table::{Report, Table};
use vl_sandbox::{Budget, Module};
use vl_sim::{Forecasting, Pilot, forecast};

use crate::{BadInput, bad_input};

/// What to regrade, and with what.
pub(crate) struct Regrading<'a> {
    pub(crate) file: &'a Path,
    /// Seeds of the twin's noise for the rerun.
    pub(crate) seeds: u32,
    /// Experiment folders, for a run of an experiment `vl` does not ship.
    pub(crate) folders: &'a [PathBuf],
}

/// The recorded run's grade, and its controller's reruns.
#[derive(Serialize)]
pub(crate) struct Regraded {
    file: String,
    experiment: Option<String>,
    /// Whose rubric graded: the experiment's own, or vl's default.
    rubric: &'static str,
    recorded: Grade,
    #[serde(skip_serializing_if = "Option::is_none")]
    rerun: Option<Rerun>,
}

/// The recorded module, run again on the twin.
#[derive(Serialize)]
struct Rerun {
    sha256: String,
    /// Where the run began, as the Host estimated it.
    start: Pose,
    seeds: Vec<RerunSeed>,
    /// Every seed ends as the recorded run did: the goal reached or not,
    /// and no contact where the run had none.
    reproduces: bool,
    /// The twin's verdict by the lab's forecast limits.
    verdict: String,
}

#[derive(Serialize)]
struct RerunSeed {
    seed: u64,
    reached_goal: bool,
    seconds: f64,
    collisions: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    fault: Option<String>,
    grade: Grade,
}

pub(crate) fn regrade(what: &Regrading<'_>) -> Result<Regraded> {
    let file = what.file;
    let recording = Recording::open(file).map_err(bad_input)?;
    let summary = recording.summary().ok_or_else(|| {
        BadInput(format!("{}: the run has no ending to grade (a Host that crashed left it: `vl record repair` keeps what it has, but a run that never ended has no grade)", file.display()))
    })?;
    let experiments = Experiments::shipped()
        .with_folders(what.folders)
        .map_err(|e| BadInput(format!("--experiments: {e}")))?;
    let declared = (summary.experiment.as_deref())
        .and_then(|id| experiments.get(id).ok())
        .and_then(|e| e.declared.rubric);
    let rubric = declared.unwrap_or_default();
    let rerun = match recording.controller() {
        None => None,
        Some(module) => Some(rerun(&recording, module, &summary, &rubric, what.seeds)?),
    };
    Ok(Regraded {
        file: file.display().to_string(),
        experiment: summary.experiment.clone(),
        rubric: match declared {
            Some(_) => "the experiment's",
            None => "vl's default",
        },
        recorded: rubric.grade(&summary),
        rerun,
    })
}

/// Runs the recorded module on the twin from the run's first pose.
fn rerun(
    recording: &Recording,
    file: &[u8],
    summary: &Summary,
    rubric: &Rubric,
    seeds: u32,
) -> Result<Rerun> {
    let definition = recording.definition().map_err(bad_input)?;
    let lab = recording.lab().map_err(bad_input)?;
    let module = Module::load(file).map_err(bad_input)?;
    if definition.controller != Some(module.hash()) {
        return Err(BadInput(format!(
            "{}: the recorded controller (sha256 {}) is not the one the run was defined with ({})",
            recording.path.display(),
            module.hash(),
            definition
                .controller
                .map_or("none".to_owned(), |h| h.to_string()),
        ))
        .into());
    }
    let start = first_pose(recording)?;
    let seeds: Vec<u64> = (1..=u64::from(seeds)).collect();
    let controllers = module.controllers(Budget::TWIN);
    let foreseen = forecast(Forecasting {
        arena: &lab.scene.arena,
        robot: &lab.scene.robot,
        start,
        definition: &definition,
        seeds: &seeds,
        cancel: None,
        pilot: Pilot::Controller(&controllers),
    })
    .map_err(bad_input)?;
    let limit_s = (definition.time_limit_s)
        .unwrap_or(vl_sim::CONTROLLER_S)
        .min(vl_sim::LONGEST_S);
    let runs: Vec<RerunSeed> = (foreseen.runs.iter())
        .map(|run| RerunSeed {
            seed: run.seed,
            reached_goal: run.reached_goal,
            seconds: run.seconds,
            collisions: run.collisions,
            fault: run.fault.clone(),
            grade: rubric.grade_measured(&run.measured(false, limit_s)),
        })
        .collect();
    let reproduces = runs.iter().all(|r| {
        r.reached_goal == summary.reached_goal && (summary.collisions > 0 || r.collisions == 0)
    });
    Ok(Rerun {
        sha256: module.hash().to_string(),
        start,
        seeds: runs,
        reproduces,
        verdict: ForecastVerdict::new(foreseen, ForecastLimits::default()).words(),
    })
}

/// The Host's first estimate of the robot in the run's file.
fn first_pose(recording: &Recording) -> Result<Pose> {
    let feedback = recording.first_feedback().ok_or_else(|| {
        BadInput(format!(
            "{}: it holds no feedback, so where the run began is unknown",
            recording.path.display()
        ))
    })?;
    Ok(feedback.pose)
}

impl Report for Regraded {
    fn table(&self) -> Table {
        let mut rows = vec![
            ("run", self.file.clone()),
            (
                "experiment",
                self.experiment
                    .clone()
                    .unwrap_or_else(|| "none named".into()),
            ),
            ("rubric", self.rubric.to_owned()),
            ("recorded run", self.recorded.comment()),
        ];
        if let Some(rerun) = &self.rerun {
            rows.push(("controller", format!("sha256 {}", rerun.sha256)));
            rows.push((
                "rerun from",
                format!(
                    "({:.0}, {:.0}) mm, {:.0}°",
                    rerun.start.x_mm,
                    rerun.start.y_mm,
                    rerun.start.theta_rad.to_degrees()
                ),
            ));
            for seed in &rerun.seeds {
                let fault = seed
                    .fault
                    .as_deref()
                    .map_or(String::new(), |f| format!(", {f}"));
                rows.push((
                    "rerun on the twin",
                    format!(
                        "seed {}: {} in {:.1} s, {} contacts{fault} — {:.1} of {:.0}",
                        seed.seed,
                        if seed.reached_goal {
                            "done"
                        } else {
                            "not done"
                        },
                        seed.seconds,
                        seed.collisions,
                        seed.grade.given,
                        seed.grade.maximum
                    ),
                ));
            }
            rows.push(("twin's verdict", rerun.verdict.clone()));
            rows.push((
                "reproduces",
                match rerun.reproduces {
                    true => "yes: every seed ends as the run did".into(),
                    false => "no: some seed ends otherwise than the run (see above)".into(),
                },
            ));
        }
        Table::pairs(rows).title("the run, graded again:")
    }
}
