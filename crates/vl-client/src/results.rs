//! A run's results, plotted from its recording: the planned, followed and
//! forecast paths over the floor, the tracking error, the wheel speeds and
//! the force over time, and the round trip — what a student hands in and a
//! teacher grades, beside the replay.

use vl_core::{Feedback, HostMessage, Point, distance_to_polyline};

use std::path::PathBuf;

use crate::client::Incoming;
use crate::plots::{self, Marks, PlotError};

/// A series of (x, y) points.
pub type Series = Vec<[f64; 2]>;

/// What the plots draw, read once from the recording.
#[derive(Debug, Clone, Default)]
pub struct Results {
    /// The arena the run was on: its floor and obstacles, drawn under the paths.
    pub arena: Option<vl_core::Arena>,
    pub planned: Series,
    pub followed: Series,
    /// Each seed's forecast path.
    pub forecast: Vec<Series>,
    /// Against the run's time, s.
    pub tracking_error_mm: Series,
    pub left_mm_s: Series,
    pub right_mm_s: Series,
    pub force: Series,
    pub round_trip_ms: Series,
}

fn xy(p: Point) -> [f64; 2] {
    [p.x_mm, p.y_mm]
}

impl Results {
    /// The results of the run in `items` (what a replay feeds, with its
    /// time in s) and the round trips measured during it (time, ms).
    pub(crate) fn of(items: &[(f64, Incoming)], round_trips: Series) -> Results {
        let mut results = Results {
            round_trip_ms: round_trips,
            ..Results::default()
        };
        let mut path: Vec<Point> = Vec::new();
        for (t, incoming) in items {
            let Incoming::Message(message) = incoming else {
                continue;
            };
            match &**message {
                HostMessage::Mounted(lab) => {
                    results.arena = Some(lab.scene.arena.clone());
                }
                HostMessage::Defined { definition } => {
                    path = definition.path.clone();
                    results.planned = path.iter().map(|&p| xy(p)).collect();
                }
                HostMessage::Forecast(verdict) => {
                    results.forecast = verdict
                        .forecast
                        .runs
                        .iter()
                        .map(|run| run.path.iter().map(|&p| xy(p)).collect())
                        .collect();
                }
                HostMessage::Feedback(Feedback {
                    pose,
                    wheels,
                    force,
                    ..
                }) => {
                    results.followed.push(xy(pose.point()));
                    if path.len() >= 2 {
                        let error = distance_to_polyline(&path, pose.point());
                        results.tracking_error_mm.push([*t, error]);
                    }
                    results.left_mm_s.push([*t, wheels.left_mm_s]);
                    results.right_mm_s.push([*t, wheels.right_mm_s]);
                    if let Some([fx, fy]) = force {
                        results.force.push([*t, fx.hypot(*fy)]);
                    }
                }
                _ => {}
            }
        }
        results
    }

    /// The plots as SVG and PNG pictures in `dir`: the paths, the tracking
    /// error, the force (when there was one) and the round trip. Their
    /// names (the PNGs').
    pub fn save(&self, dir: &std::path::Path) -> Result<Vec<PathBuf>, PlotError> {
        let series = |label: &str, colour, s: &Series| {
            (
                label.to_owned(),
                colour,
                s.iter().map(|&[x, y]| (x, y)).collect::<Vec<_>>(),
            )
        };
        let points = |s: &Series| s.iter().map(|&[x, y]| Point { x_mm: x, y_mm: y }).collect();
        let planned: Vec<Point> = points(&self.planned);
        // One seed's forecast under the path followed, drawn last to show.
        let mut taken: Vec<_> = self
            .forecast
            .first()
            .map(|run| ("forecast".to_owned(), plots::THIRD, points(run)))
            .into_iter()
            .collect();
        taken.push(("followed".to_owned(), plots::EVENT, points(&self.followed)));
        let mut saved = Vec::new();
        if let Some(arena) = &self.arena {
            saved.push(plots::paths(
                dir,
                "paths",
                "planned, followed and forecast",
                arena,
                &planned,
                &taken,
            )?);
        }
        let over_time = [
            (
                "tracking",
                "off the planned path",
                "mm",
                &self.tracking_error_mm,
            ),
            ("force", "force fed back", "force", &self.force),
            ("round_trip", "round trip", "ms", &self.round_trip_ms),
        ];
        for (name, title, unit, s) in over_time {
            if !s.is_empty() {
                let lines = [series(title, plots::EVENT, s)];
                // Round trips are pinged every 200 ms: points, not a line.
                let marks = if name == "round_trip" {
                    Marks::Points
                } else {
                    Marks::Lines
                };
                saved.push(plots::lines(dir, name, title, ("s", unit), &lines, marks)?);
            }
        }
        Ok(saved)
    }
}
