//! A definition's forecast as Guest and Host share it (issue 29): what the
//! lab's twin foresaw over a few seeds of noise, the lab's limits on it,
//! the verdict with its reasons in words, and, once the run is over, how
//! far the run was from what was foreseen. `vl-sim` makes the forecast;
//! this is what it says.

use serde::{Deserialize, Serialize};

use crate::navigation::analysis::distance_to_polyline;
use crate::{EndReason, Measured, Point, Summary};
use vl_report::table::{Report, Table};

/// What a closest approach was to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Nearest {
    Wall,
    /// The arena's obstacle of this index (from 0).
    Obstacle(usize),
    /// The definition's virtual obstacle of this index (from 0).
    VirtualObstacle(usize),
}

impl std::fmt::Display for Nearest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Nearest::Wall => f.write_str("a wall"),
            // A map the camera made is many small boxes: their numbers
            // mean nothing to a user, who is shown where instead.
            Nearest::Obstacle(_) => f.write_str("an obstacle"),
            Nearest::VirtualObstacle(i) => write!(f, "virtual obstacle {}", i + 1),
        }
    }
}

/// The least room the body had, where, and to what.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Closest {
    pub mm: f64,
    pub at: Point,
    pub to: Nearest,
}

/// One seed's forecast run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SeedRun {
    pub seed: u64,
    pub reached_goal: bool,
    /// Until the goal, or the run's time limit.
    pub seconds: f64,
    /// The least room between the body and anything (walls, obstacles,
    /// virtual obstacles).
    pub closest: Closest,
    /// The room where the run ended, and to what.
    pub end: Closest,
    pub collisions: u64,
    /// Where the first contact was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_contact: Option<Point>,
    /// How long the safety layer changed what the follower asked, s.
    pub held_back_s: f64,
    /// How long the follower asked more of a wheel than it (or the
    /// definition's cap) allows, s.
    pub saturated_s: f64,
    /// Mean distance from the defined path, mm.
    pub mean_error_mm: f64,
    /// Where the robot went, a point every `Forecast::path_every_s`.
    pub path: Vec<Point>,
    /// What stopped a user's controller, if something did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fault: Option<String>,
}

/// A definition's forecast: one run per seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Forecast {
    pub runs: Vec<SeedRun>,
    /// The time between two points of a run's path, s.
    pub path_every_s: f64,
}

/// The least, mean and most of some figure over the seeds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Spread {
    pub least: f64,
    pub mean: f64,
    pub most: f64,
}

impl Spread {
    fn of(values: impl Iterator<Item = f64>) -> Spread {
        let (mut least, mut most, mut sum, mut n) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0);
        for v in values {
            (least, most, sum, n) = (least.min(v), most.max(v), sum + v, n + 1);
        }
        Spread {
            least,
            mean: sum / f64::from(n.max(1)),
            most,
        }
    }
}

impl std::fmt::Display for Spread {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.most - self.least < 0.05 {
            write!(f, "{:.1}", self.mean)
        } else {
            write!(f, "{:.1} ({:.1}–{:.1})", self.mean, self.least, self.most)
        }
    }
}

impl SeedRun {
    /// The run's measures for a rubric, as a live run's would be: `tracked`
    /// when it followed a defined path, `limit_s` its time limit. The gap
    /// to a forecast is not measured: this is the forecast.
    pub fn measured(&self, tracked: bool, limit_s: f64) -> Measured {
        let reason = match (self.reached_goal, &self.fault) {
            (true, _) => EndReason::GoalReached,
            (false, Some(_)) => EndReason::Fault,
            // Within a simulator step of the limit: the limit ended it.
            (false, None) if self.seconds >= limit_s - 0.01 => EndReason::TimeLimit,
            (false, None) => EndReason::ControllerDone,
        };
        Measured {
            reached_goal: self.reached_goal,
            reason,
            collisions: self.collisions,
            waypoints: None,
            tracking_mm: tracked.then_some(self.mean_error_mm),
            seconds: self.seconds,
            forecast_gap_mm: None,
            distance_mm: self.path.windows(2).map(|w| w[0].distance(w[1])).sum(),
        }
    }
}

impl Forecast {
    /// How many seeds reach the goal.
    pub fn reached(&self) -> usize {
        self.runs.iter().filter(|r| r.reached_goal).count()
    }

    /// The time to the goal over the seeds that reach it.
    pub fn seconds(&self) -> Spread {
        Spread::of(
            self.runs
                .iter()
                .filter(|r| r.reached_goal)
                .map(|r| r.seconds),
        )
    }

    /// The closest approach over every seed.
    pub fn closest(&self) -> Option<Closest> {
        self.runs
            .iter()
            .map(|r| r.closest)
            .min_by(|a, b| a.mm.total_cmp(&b.mm))
    }

    pub fn collisions(&self) -> u64 {
        self.runs.iter().map(|r| r.collisions).sum()
    }

    pub fn held_back_s(&self) -> Spread {
        Spread::of(self.runs.iter().map(|r| r.held_back_s))
    }

    pub fn saturated_s(&self) -> Spread {
        Spread::of(self.runs.iter().map(|r| r.saturated_s))
    }

    pub fn mean_error_mm(&self) -> Spread {
        Spread::of(self.runs.iter().map(|r| r.mean_error_mm))
    }

    /// What the lab's `limits` find wrong with it; empty when it passes.
    pub fn judge(&self, limits: &ForecastLimits) -> Vec<ForecastRefusal> {
        let mut wrong = Vec::new();
        let seeds = self.runs.len();
        if let Some(why) = self.runs.iter().find_map(|r| r.fault.clone()) {
            wrong.push(ForecastRefusal::Stopped {
                why,
                seeds: self.runs.iter().filter(|r| r.fault.is_some()).count(),
                of: seeds,
            });
        }
        if let Some(run) = self.runs.iter().find(|r| r.collisions > 0) {
            wrong.push(ForecastRefusal::Contact {
                at: run.first_contact.unwrap_or(run.closest.at),
                to: run.closest.to,
                seeds: self.runs.iter().filter(|r| r.collisions > 0).count(),
                of: seeds,
            });
        }
        if let Some(run) = self.runs.iter().find(|r| !r.reached_goal) {
            wrong.push(ForecastRefusal::NoGoal {
                stops: run.end,
                seeds: seeds - self.reached(),
                of: seeds,
            });
        }
        if let Some(closest) = self.closest()
            && closest.mm < limits.min_clearance_mm
            && self.collisions() == 0
        {
            wrong.push(ForecastRefusal::TooClose {
                closest,
                limit_mm: limits.min_clearance_mm,
            });
        }
        let slowest = self.runs.iter().map(|r| r.seconds).fold(0.0, f64::max);
        if let Some(limit_s) = limits.max_seconds
            && self.reached() == seeds
            && slowest > limit_s
        {
            wrong.push(ForecastRefusal::TooLong {
                seconds: slowest,
                limit_s,
            });
        }
        wrong
    }

    /// How far `run` was from this forecast: its time, path and closest
    /// approach against the foreseen ones.
    pub fn gap(&self, run: &Summary) -> Option<Gap> {
        let analysis = run.path.as_ref()?;
        let taken = match analysis.truth.is_empty() {
            true => &analysis.estimated,
            false => &analysis.truth,
        };
        if taken.is_empty() || self.runs.is_empty() {
            return None;
        }
        let (mut mean_sum, mut max) = (0.0, 0.0_f64);
        for seed in &self.runs {
            let d: Vec<f64> = taken
                .iter()
                .map(|&p| distance_to_polyline(&seed.path, p))
                .collect();
            mean_sum += d.iter().sum::<f64>() / d.len() as f64;
            max = d.iter().copied().fold(max, f64::max);
        }
        let foreseen = self.seconds();
        Some(Gap {
            forecast_s: (self.reached() > 0).then_some(foreseen.mean),
            run_s: run.seconds,
            path_mean_mm: mean_sum / self.runs.len() as f64,
            path_max_mm: max,
            forecast_closest_mm: self.closest().map(|c| c.mm),
            run_closest_mm: run.closest_mm,
        })
    }
}

/// What a lab asks of a definition's forecast besides reaching the goal
/// without contact (`lab.toml` or `vl host` flags).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ForecastLimits {
    /// The least room the body may come to anything, mm.
    pub min_clearance_mm: f64,
    /// The longest a run may be foreseen to take, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_seconds: Option<f64>,
}

impl Default for ForecastLimits {
    fn default() -> Self {
        ForecastLimits {
            min_clearance_mm: 0.0,
            max_seconds: None,
        }
    }
}

/// Why a forecast does not pass.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ForecastRefusal {
    /// The robot would touch something.
    Contact {
        at: Point,
        to: Nearest,
        seeds: usize,
        of: usize,
    },
    /// The robot would not reach the goal; where it ends up, and how near
    /// to what.
    NoGoal {
        stops: Closest,
        seeds: usize,
        of: usize,
    },
    /// The robot would come nearer to something than the lab allows.
    TooClose { closest: Closest, limit_mm: f64 },
    /// The run would take longer than the lab allows.
    TooLong { seconds: f64, limit_s: f64 },
    /// The user's controller would be stopped (a trap, its fuel, its
    /// memory, speeds that are no numbers); why, on the first seed.
    Stopped {
        why: String,
        seeds: usize,
        of: usize,
    },
}

impl ForecastRefusal {
    /// Where on the arena the trouble is, to be shown there.
    pub fn at(&self) -> Option<Point> {
        match self {
            ForecastRefusal::Contact { at, .. } => Some(*at),
            ForecastRefusal::NoGoal { stops, .. } => Some(stops.at),
            ForecastRefusal::TooClose { closest, .. } => Some(closest.at),
            ForecastRefusal::TooLong { .. } | ForecastRefusal::Stopped { .. } => None,
        }
    }
}

impl std::fmt::Display for ForecastRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let xy = |p: &Point| format!("({:.0}, {:.0}) mm", p.x_mm, p.y_mm);
        match self {
            ForecastRefusal::Contact { at, to, seeds, of } => write!(
                f,
                "the robot would touch {to} at {} ({seeds} of {of} tries)",
                xy(at)
            ),
            ForecastRefusal::NoGoal { stops, seeds, of } => write!(
                f,
                "the robot would not reach the goal: it stops at {}, {:.1} mm from {} ({seeds} of {of} tries)",
                xy(&stops.at),
                stops.mm,
                stops.to
            ),
            ForecastRefusal::TooClose { closest, limit_mm } => write!(
                f,
                "the robot would pass {:.1} mm from {} at {}; this lab keeps {limit_mm:.0} mm",
                closest.mm,
                closest.to,
                xy(&closest.at)
            ),
            ForecastRefusal::TooLong { seconds, limit_s } => write!(
                f,
                "the run would take {seconds:.1} s; this lab allows {limit_s:.0} s"
            ),
            ForecastRefusal::Stopped { why, seeds, of } => {
                write!(f, "{why} ({seeds} of {of} tries)")
            }
        }
    }
}

/// A definition's forecast and the lab's verdict on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ForecastVerdict {
    pub forecast: Forecast,
    pub limits: ForecastLimits,
    /// Empty when the forecast passed.
    pub refusals: Vec<ForecastRefusal>,
}

impl ForecastVerdict {
    pub fn new(forecast: Forecast, limits: ForecastLimits) -> ForecastVerdict {
        ForecastVerdict {
            refusals: forecast.judge(&limits),
            forecast,
            limits,
        }
    }

    pub fn passed(&self) -> bool {
        self.refusals.is_empty()
    }
}

impl ForecastVerdict {
    /// The forecast's figures in words, for a table or a panel.
    pub fn figures(&self) -> Vec<(&'static str, String)> {
        let f = &self.forecast;
        let mut rows = vec![
            (
                "reaches the goal",
                format!("{} of {} tries", f.reached(), f.runs.len()),
            ),
            (
                "time to the goal",
                match f.reached() {
                    0 => "never".to_owned(),
                    _ => format!("{} s", f.seconds()),
                },
            ),
        ];
        if let Some(c) = f.closest() {
            rows.push((
                "closest approach",
                format!(
                    "{:.1} mm to {} at ({:.0}, {:.0})",
                    c.mm, c.to, c.at.x_mm, c.at.y_mm
                ),
            ));
        }
        rows.extend([
            ("contacts", f.collisions().to_string()),
            ("held back", format!("{} s", f.held_back_s())),
            ("wheels saturated", format!("{} s", f.saturated_s())),
            ("off the path", format!("{} mm", f.mean_error_mm())),
        ]);
        rows
    }

    /// The verdict in words: passed, or refused and why.
    pub fn words(&self) -> String {
        match self.passed() {
            true => "passed: the run may start".to_owned(),
            false => {
                let why: Vec<String> = self.refusals.iter().map(|r| r.to_string()).collect();
                format!("refused: {}", why.join("; "))
            }
        }
    }
}

impl Report for ForecastVerdict {
    fn table(&self) -> Table {
        let mut rows = self.figures();
        rows.push(("verdict", self.words()));
        Table::pairs(rows).title("the definition, tried on the lab's twin:")
    }
}

/// A run against its forecast: the twin's honesty, run by run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Gap {
    /// The foreseen time to the goal (mean over the seeds that reach it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forecast_s: Option<f64>,
    pub run_s: f64,
    /// Distance from the path taken to the foreseen ones: mean, and most.
    pub path_mean_mm: f64,
    pub path_max_mm: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forecast_closest_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_closest_mm: Option<f64>,
}

impl Gap {
    /// The run's time off the forecast's, as a share of the forecast's.
    pub fn time_off(&self) -> Option<f64> {
        self.forecast_s
            .filter(|s| *s > 0.0)
            .map(|s| (self.run_s - s) / s)
    }
}

impl std::fmt::Display for Gap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(s) = self.forecast_s {
            write!(f, "{:.1} s against {s:.1} s foreseen, ", self.run_s)?;
        }
        write!(
            f,
            "path {:.1} mm from the forecast's (at most {:.1} mm)",
            self.path_mean_mm, self.path_max_mm
        )?;
        if let (Some(foreseen), Some(run)) = (self.forecast_closest_mm, self.run_closest_mm) {
            write!(f, ", closest {run:.1} mm against {foreseen:.1} mm")?;
        }
        Ok(())
    }
}
