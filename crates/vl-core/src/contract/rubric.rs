//! How a run is graded: points for what its summary shows (the goal
//! reached, no collisions, a path close to the plan, time, the gap to its
//! forecast), set by the teacher in the lab's config (`[rubric]` in `vl host
//! --config lab.toml`), and the grade with each line explained — what an
//! LMS receives as a score and its comment.

use serde::{Deserialize, Serialize};

use crate::{EndReason, Summary, WaypointsVisited};

/// Points per criterion and what earns them in full. A measure earns its
/// points in full up to its bound and nothing from twice the bound, linearly
/// between: a run a little slow loses a little.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Rubric {
    /// For reaching the goal.
    pub goal: f64,
    /// For the waypoints visited in order, a share for each (runs whose
    /// definition has waypoints).
    pub waypoints: f64,
    /// For a run without collisions…
    pub no_collisions: f64,
    /// …less this much for each one.
    pub per_collision: f64,
    /// For the estimated path's mean distance to the planned one within
    /// `tracking_mm`.
    pub tracking: f64,
    pub tracking_mm: f64,
    /// For a run of at most `time_s` seconds.
    pub time: f64,
    pub time_s: f64,
    /// For a path within `forecast_mm` (mean) of the forecast's.
    pub forecast: f64,
    pub forecast_mm: f64,
}

impl Default for Rubric {
    fn default() -> Self {
        Rubric {
            goal: 50.0,
            waypoints: 0.0,
            no_collisions: 20.0,
            per_collision: 10.0,
            tracking: 10.0,
            tracking_mm: 10.0,
            time: 10.0,
            time_s: 60.0,
            forecast: 10.0,
            forecast_mm: 10.0,
        }
    }
}

/// The most points a rubric gives per criterion, and the largest bound.
const MAX_POINTS: f64 = 1000.0;

/// Why a rubric cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("rubric: {0}")]
pub struct RubricError(String);

/// One line of a grade: what was measured and the points it earned.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GradeLine {
    pub criterion: &'static str,
    pub measured: String,
    pub points: f64,
    pub of: f64,
}

/// A run's grade.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Grade {
    pub given: f64,
    pub maximum: f64,
    pub lines: Vec<GradeLine>,
}

impl Grade {
    /// The grade in words, a line per criterion: the LMS's comment.
    pub fn comment(&self) -> String {
        let lines: Vec<String> = self
            .lines
            .iter()
            .map(|l| {
                format!(
                    "{}: {} — {:.1} of {:.0}",
                    l.criterion, l.measured, l.points, l.of
                )
            })
            .collect();
        format!(
            "{:.1} of {:.0}. {}",
            self.given,
            self.maximum,
            lines.join("; ")
        )
    }
}

/// What a rubric grades a run by.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    pub reached_goal: bool,
    /// Why the run ended, said when the goal was not reached.
    pub reason: EndReason,
    pub collisions: u64,
    pub waypoints: Option<WaypointsVisited>,
    /// Mean distance of the estimated path to the planned one, mm.
    pub tracking_mm: Option<f64>,
    pub seconds: f64,
    /// Mean distance of the path to its forecast's, mm.
    pub forecast_gap_mm: Option<f64>,
    pub distance_mm: f64,
}

impl Measured {
    /// A finished run's measures, from its summary.
    pub fn of(summary: &Summary) -> Measured {
        Measured {
            reached_goal: summary.reached_goal,
            reason: summary.reason,
            collisions: summary.collisions,
            waypoints: summary.waypoints,
            tracking_mm: (summary.path.as_ref())
                .and_then(|p| p.tracking_error_mm)
                .map(|e| e.mean),
            seconds: summary.seconds,
            forecast_gap_mm: summary.forecast.as_ref().map(|g| g.path_mean_mm),
            distance_mm: summary.distance_mm,
        }
    }
}

/// `points` for `value` within `bound`, none from twice it, linear between.
fn within(points: f64, value: f64, bound: f64) -> f64 {
    if !value.is_finite() {
        return 0.0;
    }
    let share = (2.0 - value / bound).clamp(0.0, 1.0);
    points * share
}

impl Rubric {
    /// The rubric, if every number is finite, not negative and at most
    /// [`MAX_POINTS`], every bound above zero, and some point may be earned.
    pub fn checked(self) -> Result<Rubric, RubricError> {
        let numbers = [
            ("goal", self.goal),
            ("waypoints", self.waypoints),
            ("no_collisions", self.no_collisions),
            ("per_collision", self.per_collision),
            ("tracking", self.tracking),
            ("tracking_mm", self.tracking_mm),
            ("time", self.time),
            ("time_s", self.time_s),
            ("forecast", self.forecast),
            ("forecast_mm", self.forecast_mm),
        ];
        for (name, value) in numbers {
            if !(0.0..=MAX_POINTS).contains(&value) {
                return Err(RubricError(format!(
                    "'{name}' is {value}: each is a number from 0 to {MAX_POINTS}"
                )));
            }
        }
        for (name, bound) in [
            ("tracking_mm", self.tracking_mm),
            ("time_s", self.time_s),
            ("forecast_mm", self.forecast_mm),
        ] {
            if bound <= 0.0 {
                return Err(RubricError(format!("'{name}' must be above 0")));
            }
        }
        if self.maximum() <= 0.0 {
            return Err(RubricError("it gives no points at all".into()));
        }
        Ok(self)
    }

    /// The most a run may earn.
    pub fn maximum(&self) -> f64 {
        self.goal + self.waypoints + self.no_collisions + self.tracking + self.time + self.forecast
    }

    /// How `summary`'s run earned its points. A measure the run did not
    /// have (no plan to track, no forecast) earns none and says so.
    pub fn grade(&self, summary: &Summary) -> Grade {
        self.grade_measured(&Measured::of(summary))
    }

    /// How a run with these measures earned its points: a live run's, or
    /// a rerun's on the twin (`vl record regrade`).
    pub fn grade_measured(&self, run: &Measured) -> Grade {
        let mut lines = vec![
            GradeLine {
                criterion: "goal",
                measured: if run.reached_goal {
                    "reached".into()
                } else {
                    format!("not reached ({})", run.reason)
                },
                points: if run.reached_goal { self.goal } else { 0.0 },
                of: self.goal,
            },
            GradeLine {
                criterion: "collisions",
                measured: run.collisions.to_string(),
                points: (self.no_collisions - self.per_collision * run.collisions as f64).max(0.0),
                of: self.no_collisions,
            },
        ];
        let visited = run.waypoints.map(|w| (w.visited, w.of));
        if self.waypoints > 0.0 {
            lines.push(GradeLine {
                criterion: "waypoints",
                measured: visited.map_or("none defined".into(), |(v, of)| {
                    format!("{v} of {of} visited in order")
                }),
                points: visited.map_or(0.0, |(v, of)| self.waypoints * v as f64 / of.max(1) as f64),
                of: self.waypoints,
            });
        }
        lines.push(self.measure(
            "tracking",
            run.tracking_mm,
            self.tracking,
            self.tracking_mm,
            "mm",
        ));
        lines.push(self.measure("time", Some(run.seconds), self.time, self.time_s, "s"));
        let gap = run.forecast_gap_mm;
        lines.push(self.measure("forecast", gap, self.forecast, self.forecast_mm, "mm"));
        // Points only for a run that went somewhere: standing still is
        // neither quick nor on the path.
        if !run.reached_goal && run.distance_mm < 1.0 {
            for line in lines.iter_mut().filter(|l| l.criterion != "collisions") {
                line.points = 0.0;
            }
        }
        Grade {
            given: lines.iter().map(|l| l.points).sum(),
            maximum: self.maximum(),
            lines,
        }
    }

    fn measure(
        &self,
        criterion: &'static str,
        value: Option<f64>,
        points: f64,
        bound: f64,
        unit: &str,
    ) -> GradeLine {
        match value {
            Some(v) => GradeLine {
                criterion,
                measured: format!("{v:.1} {unit} (full points within {bound} {unit})"),
                points: within(points, v, bound),
                of: points,
            },
            None => GradeLine {
                criterion,
                measured: "not measured in this run".into(),
                points: 0.0,
                of: points,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EndReason, Pose, PoseSource};
    use proptest::prelude::*;

    fn summary(reached: bool, collisions: u64, seconds: f64, distance_mm: f64) -> Summary {
        Summary {
            experiment: None,
            reason: if reached {
                EndReason::GoalReached
            } else {
                EndReason::Stopped
            },
            reached_goal: reached,
            events: 10,
            final_pose: Pose::default(),
            seconds,
            distance_mm,
            collisions,
            closest_mm: None,
            speed_kept: None,
            pose_source: PoseSource::default(),
            path: None,
            max_event_gap: 0,
            sync_violations: 0,
            stopped_by: None,
            held_back: None,
            fault: None,
            forecast: None,
            recording: None,
            waypoints: None,
        }
    }

    #[test]
    fn a_clean_quick_run_to_the_goal_earns_what_it_measured() {
        let rubric = Rubric::default();
        let grade = rubric.grade(&summary(true, 0, 30.0, 800.0));
        // Goal, no collisions and time in full; tracking and forecast were
        // not measured.
        assert_eq!(grade.given, 80.0);
        assert_eq!(grade.maximum, 100.0);
        let comment = grade.comment();
        assert!(comment.starts_with("80.0 of 100."), "{comment}");
        assert!(comment.contains("tracking: not measured"), "{comment}");
        let slow = rubric.grade(&summary(true, 1, 90.0, 800.0));
        assert_eq!(slow.given, 50.0 + 10.0 + 5.0);
    }

    #[test]
    fn a_navigation_run_earns_for_its_path_and_forecast() {
        let mut run = summary(true, 0, 30.0, 800.0);
        run.path = Some(crate::PathAnalysis {
            tracking_error_mm: Some(crate::ErrorMm {
                mean: 4.0,
                max: 9.0,
                rms: 5.0,
            }),
            estimated: Vec::new(),
            truth: Vec::new(),
            path_error_mm: None,
            estimate_error_mm: None,
        });
        run.forecast = Some(crate::Gap {
            forecast_s: Some(29.0),
            run_s: 30.0,
            path_mean_mm: 12.0,
            path_max_mm: 30.0,
            forecast_closest_mm: None,
            run_closest_mm: None,
        });
        let grade = Rubric::default().grade(&run);
        // Tracking within its 10 mm: in full; the forecast 12 mm off where
        // 10 is full and 20 nothing: 8 of 10.
        assert_eq!(grade.given, 50.0 + 20.0 + 10.0 + 10.0 + 8.0);
        assert!(
            grade.comment().contains("forecast: 12.0 mm"),
            "{}",
            grade.comment()
        );
    }

    #[test]
    fn bad_rubrics_are_refused_by_name() {
        let nan = Rubric {
            time: f64::NAN,
            ..Rubric::default()
        };
        assert!(nan.checked().unwrap_err().to_string().contains("'time'"));
        let zero = Rubric {
            time_s: 0.0,
            ..Rubric::default()
        };
        assert!(zero.checked().unwrap_err().to_string().contains("time_s"));
    }

    proptest! {
        #[test]
        fn a_grade_is_within_its_maximum_and_fewer_collisions_never_earn_less(
            reached: bool,
            collisions in 0u64..1000,
            seconds in prop_oneof![Just(f64::INFINITY), Just(f64::NAN), 0.0f64..1e6],
            distance in 0.0f64..1e5,
            goal in 0.0f64..100.0,
            per in 0.0f64..50.0,
        ) {
            let rubric = Rubric { goal, per_collision: per, ..Rubric::default() }.checked().unwrap();
            let grade = rubric.grade(&summary(reached, collisions, seconds, distance));
            prop_assert!(grade.given.is_finite());
            prop_assert!((0.0..=grade.maximum + 1e-9).contains(&grade.given));
            prop_assert_eq!(grade.lines.len(), 5);
            if collisions > 0 {
                let fewer = rubric.grade(&summary(reached, collisions - 1, seconds, distance));
                prop_assert!(fewer.given >= grade.given);
            }
        }
    }

    #[test]
    fn waypoints_earn_a_share_each_and_no_line_without_points_for_them() {
        let rubric = Rubric {
            waypoints: 40.0,
            ..Rubric::default()
        };
        let mut run = summary(false, 0, 30.0, 800.0);
        run.waypoints = Some(crate::WaypointsVisited { visited: 3, of: 4 });
        let grade = rubric.grade(&run);
        let line = grade
            .lines
            .iter()
            .find(|l| l.criterion == "waypoints")
            .unwrap();
        assert_eq!((line.points, line.of), (30.0, 40.0));
        assert_eq!(line.measured, "3 of 4 visited in order");
        assert_eq!(grade.maximum, 140.0);
        let plain = Rubric::default().grade(&run);
        assert!(plain.lines.iter().all(|l| l.criterion != "waypoints"));
    }

    /// A twin's rerun is graded as a live run of the same measures, its
    /// ending told from the run: the goal, a fault, the limit, or the
    /// controller's own "done" short of it.
    #[test]
    fn a_twin_s_rerun_is_graded_as_a_run_with_its_measures() {
        use crate::{Closest, Nearest, Point, SeedRun};
        let at = Point {
            x_mm: 0.0,
            y_mm: 0.0,
        };
        let closest = Closest {
            mm: 40.0,
            at,
            to: Nearest::Wall,
        };
        let run = |reached_goal, seconds, fault: Option<&str>| SeedRun {
            seed: 1,
            reached_goal,
            seconds,
            closest,
            end: closest,
            collisions: 0,
            first_contact: None,
            held_back_s: 0.0,
            saturated_s: 0.0,
            mean_error_mm: 3.0,
            path: vec![
                at,
                Point {
                    x_mm: 300.0,
                    y_mm: 400.0,
                },
            ],
            fault: fault.map(str::to_owned),
        };
        let reached = run(true, 30.0, None).measured(false, 60.0);
        assert_eq!(reached.reason, EndReason::GoalReached);
        assert_eq!(reached.distance_mm, 500.0);
        assert_eq!(reached.tracking_mm, None);
        let live = summary(true, 0, 30.0, 500.0);
        assert_eq!(
            Rubric::default().grade_measured(&reached),
            Rubric::default().grade(&live)
        );
        for (seconds, fault, reason) in [
            (12.0, Some("it trapped"), EndReason::Fault),
            (60.0, None, EndReason::TimeLimit),
            (12.0, None, EndReason::ControllerDone),
        ] {
            assert_eq!(
                run(false, seconds, fault).measured(false, 60.0).reason,
                reason
            );
        }
        assert_eq!(
            run(true, 30.0, None).measured(true, 60.0).tracking_mm,
            Some(3.0)
        );
    }
}
