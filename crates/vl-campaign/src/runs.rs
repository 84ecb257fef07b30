//! A series of runs of one experiment (`vl experiment run`): each run's
//! figures in a row and the errors over all of them.

use serde::Serialize;
use vl_core::ErrorMm;
use vl_report::table::{Report, Table, count, yes};

use std::path::Path;

use vl_core::Arena;
use vl_sim::Optics;

use super::{
    CampaignError, MeasuredRun, RunSpec, overall, picture, progress_line, run_one, spread,
};

/// A series of runs of one experiment and what they add up to.
#[derive(Serialize)]
pub struct RunSeries {
    pub runs: Vec<MeasuredRun>,
    /// Every run reached its goal without touching anything.
    pub all_succeeded: bool,
    /// Over all runs: the mean of their mean tracking errors, and the largest.
    pub tracking_error_mm: Option<ErrorMm>,
    pub estimate_error_mm: Option<ErrorMm>,
}

fn mm(e: Option<ErrorMm>, pick: fn(&ErrorMm) -> f64) -> String {
    e.map_or("–".into(), |e| format!("{:.1}", pick(&e)))
}

impl Report for RunSeries {
    fn table(&self) -> Table {
        let mut table = Table::columns(&[
            "arena",
            "seed",
            "goal",
            "collisions",
            "track mean",
            "track max",
            "estimate max",
            "gap",
            "sync lost",
            "predict mean",
            "stale mean",
            "seconds",
            "forecast s",
            "fc path",
            "video kB",
        ]);
        for run in &self.runs {
            table.row(vec![
                run.arena.clone(),
                run.seed.to_string(),
                yes(run.reached_goal).into(),
                run.collisions.to_string(),
                mm(run.tracking_error_mm, |e| e.mean),
                mm(run.tracking_error_mm, |e| e.max),
                mm(run.estimate_error_mm, |e| e.max),
                run.max_event_gap.to_string(),
                run.sync_violations.to_string(),
                spread(run.prediction_error_mm),
                spread(run.stale_error_mm),
                format!("{:.2}", run.completion_s),
                (run.forecast.and_then(|g| g.forecast_s))
                    .map_or("–".into(), |s| format!("{s:.2}")),
                run.forecast
                    .map_or("–".into(), |g| format!("{:.1}", g.path_mean_mm)),
                format!("{:.0}", run.video_bytes as f64 / 1e3),
            ]);
        }
        let failed = self.runs.iter().filter(|r| !r.succeeded()).count();
        let mut table = table.title(
            "errors in mm; tracking: the true pose to the planned path; estimate: the \
             estimate to the true pose; gap: the largest command event ahead of the feedback \
             it was sent on; predict/stale: the predicted / last reported pose against the \
             feedback that came next; forecast s: the run's time on the lab's twin; fc path: \
             the run's path to the twin's, mean",
        );
        table = table.note(format!(
            "{}; {} failed; tracking error over all: {}{}",
            count(self.runs.len() as u64, "run", "runs"),
            failed,
            ErrorMm::cell(self.tracking_error_mm),
            twin_words(&self.runs)
        ));
        table
    }
}

/// How far the runs were from their forecasts, at most, in words.
fn twin_words(runs: &[MeasuredRun]) -> String {
    let gaps: Vec<vl_core::Gap> = runs.iter().filter_map(|r| r.forecast).collect();
    if gaps.is_empty() {
        return String::new();
    }
    let time = gaps
        .iter()
        .filter_map(vl_core::Gap::time_off)
        .fold(0.0, |most: f64, off| most.max(off.abs()));
    let path = gaps.iter().map(|g| g.path_mean_mm).fold(0.0, f64::max);
    format!(
        "; against their forecasts: time off by at most {:.0} %, paths at most {path:.1} mm apart (mean)",
        time * 100.0
    )
}

impl RunSeries {
    /// Runs `template` `runs` times on each of `arenas`, run k with seed
    /// `template.seed + k` (the lab's, the camera's and the link's); a
    /// picture of each into `svg` when given; a line on stderr after each
    /// when `progress`.
    pub async fn run(
        template: &RunSpec,
        arenas: &[Arena],
        runs: u64,
        svg: Option<&Path>,
        progress: bool,
    ) -> Result<RunSeries, CampaignError> {
        let total = arenas.len() as u64 * runs;
        let mut done = Vec::new();
        for arena in arenas {
            for k in 0..runs {
                let seed = template.seed + k;
                let spec = RunSpec {
                    arena: arena.clone(),
                    seed,
                    optics: Optics {
                        seed,
                        ..template.optics
                    },
                    ..template.clone()
                };
                let mut run = run_one(&spec).await?;
                if let Some(dir) = svg {
                    run.svg = Some(picture(dir, arena, seed, run.report.as_ref())?);
                }
                if progress {
                    eprintln!("[{}/{total}] {}", done.len() + 1, progress_line(&run));
                }
                done.push(run);
            }
        }
        Ok(RunSeries::of(done))
    }

    /// The runs and their totals.
    pub fn of(runs: Vec<MeasuredRun>) -> RunSeries {
        RunSeries {
            tracking_error_mm: overall(&runs, |r| r.tracking_error_mm),
            estimate_error_mm: overall(&runs, |r| r.estimate_error_mm),
            all_succeeded: runs.iter().all(MeasuredRun::succeeded),
            runs,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::tests::run;
    use vl_client::Pacing;

    #[test]
    fn one_failed_run_fails_the_series_and_its_errors_count() {
        let ok = run("navigation", Pacing::Event, "lan", true, 2.0, 1.0);
        let failed = run("navigation", Pacing::Event, "lan", false, 4.0, 1.0);
        let runs = RunSeries::of(vec![ok.clone()]);
        assert!(runs.all_succeeded);
        let both = RunSeries::of(vec![ok, failed]);
        assert!(!both.all_succeeded);
        let e = both.tracking_error_mm.expect("two runs were tracked");
        assert_eq!((e.mean, e.max), (3.0, 8.0));
        let text = both.table().to_string();
        assert!(text.contains("2 runs; 1 failed"), "{text}");
    }

    #[test]
    fn no_runs_succeed_vacuously_with_no_errors() {
        let none = RunSeries::of(Vec::new());
        assert!(none.all_succeeded && none.tracking_error_mm.is_none());
    }
}
