//! Path analysis (thesis §7.4.2): how far the followed path strayed from the
//! planned one. A run records its estimated poses and, in simulation, the
//! true ones; the summary carries both paths (thinned for drawing) and the
//! error statistics between them and the plan.

use serde::{Deserialize, Serialize};

use crate::{Point, Pose};

/// Where the pose a run steered from came from.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum PoseSource {
    /// The overhead camera, with odometry between frames.
    Camera,
    /// The wheels' odometry alone.
    #[default]
    Odometry,
}

impl std::fmt::Display for PoseSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PoseSource::Camera => "camera",
            PoseSource::Odometry => "odometry",
        })
    }
}

/// Mean, largest and root-mean-square of a set of distances, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ErrorMm {
    pub mean: f64,
    pub max: f64,
    pub rms: f64,
}

impl ErrorMm {
    /// The statistics in a table cell; a dash when nothing was measured.
    pub fn cell(e: Option<ErrorMm>) -> String {
        e.map_or("–".into(), |e| {
            format!(
                "mean {:.1} mm, max {:.1} mm, rms {:.1} mm",
                e.mean, e.max, e.rms
            )
        })
    }
}

/// Running sums behind an [`ErrorMm`].
#[derive(Debug, Clone, Copy, Default)]
struct Errors {
    n: u64,
    sum: f64,
    sum_sq: f64,
    max: f64,
}

impl Errors {
    fn add(&mut self, e: f64) {
        self.n += 1;
        self.sum += e;
        self.sum_sq += e * e;
        self.max = self.max.max(e);
    }

    fn stats(&self) -> Option<ErrorMm> {
        (self.n > 0).then(|| ErrorMm {
            mean: self.sum / self.n as f64,
            max: self.max,
            rms: (self.sum_sq / self.n as f64).sqrt(),
        })
    }
}

/// The `q`-quantile (0..=1) of `sorted` (ascending) by nearest rank; none
/// when there is nothing to rank. The one way round trips and delays are
/// summarised.
pub fn nearest_rank(sorted: &[f64], q: f64) -> Option<f64> {
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len().max(1));
    sorted.get(rank - 1).copied()
}

/// Distance from `p` to the polyline through `path`; infinite for no path.
/// Compared squared, with one root at the end: a follower measures it
/// every step against the whole path, and a root per segment was most of a
/// forecast's time. Coordinates too large to square are measured as before.
pub fn distance_to_polyline(path: &[Point], p: Point) -> f64 {
    let squared = |a: Point, b: Point| {
        let (dx, dy) = (b.x_mm - a.x_mm, b.y_mm - a.y_mm);
        let len2 = dx * dx + dy * dy;
        let t = match len2 > 0.0 {
            true => (((p.x_mm - a.x_mm) * dx + (p.y_mm - a.y_mm) * dy) / len2).clamp(0.0, 1.0),
            false => 0.0,
        };
        let (ex, ey) = (p.x_mm - (a.x_mm + t * dx), p.y_mm - (a.y_mm + t * dy));
        ex * ex + ey * ey
    };
    match path {
        [] => f64::INFINITY,
        [only] => p.distance(*only),
        _ => {
            let least = path
                .windows(2)
                .map(|s| squared(s[0], s[1]))
                .fold(f64::INFINITY, f64::min);
            match least.is_finite() {
                true => least.sqrt(),
                false => path
                    .windows(2)
                    .map(|s| p.distance_to_segment(s[0], s[1]))
                    .fold(f64::INFINITY, f64::min),
            }
        }
    }
}

/// A finished run's paths and their errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PathAnalysis {
    /// The path as the Host estimated it, thinned to a point per few mm.
    pub estimated: Vec<Point>,
    /// The path the robot truly took (simulation only), thinned alike.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub truth: Vec<Point>,
    /// Estimated pose to the planned path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracking_error_mm: Option<ErrorMm>,
    /// True pose to the planned path: what the robot really did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path_error_mm: Option<ErrorMm>,
    /// Estimated pose to the true one at the same instant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_error_mm: Option<ErrorMm>,
}

/// Samples closer than this to the last kept one are not kept for drawing, mm.
const THIN_MM: f64 = 5.0;
/// The most points kept per drawn path: a run across the largest arena
/// and back several times.
const MAX_DRAWN: usize = 4000;

/// Collects a run's samples into a [`PathAnalysis`].
#[derive(Debug, Clone, Default)]
pub struct PathRecorder {
    planned: Vec<Point>,
    estimated: Vec<Point>,
    truth: Vec<Point>,
    tracking: Errors,
    path: Errors,
    estimate: Errors,
}

impl PathRecorder {
    /// Compares what follows with `planned` (empty: no plan to compare with).
    pub fn new(planned: Vec<Point>) -> PathRecorder {
        PathRecorder {
            planned,
            ..PathRecorder::default()
        }
    }

    /// One instant of the run: the estimate, and the truth where known.
    pub fn record(&mut self, estimate: Pose, truth: Option<Pose>) {
        let e = estimate.point();
        keep(&mut self.estimated, e);
        if !self.planned.is_empty() {
            self.tracking.add(distance_to_polyline(&self.planned, e));
        }
        if let Some(t) = truth.map(|t| t.point()) {
            keep(&mut self.truth, t);
            self.estimate.add(e.distance(t));
            if !self.planned.is_empty() {
                self.path.add(distance_to_polyline(&self.planned, t));
            }
        }
    }

    pub fn finish(self) -> PathAnalysis {
        PathAnalysis {
            estimated: self.estimated,
            truth: self.truth,
            tracking_error_mm: self.tracking.stats(),
            path_error_mm: self.path.stats(),
            estimate_error_mm: self.estimate.stats(),
        }
    }
}

/// Appends `p` when it is far enough from the last point kept.
fn keep(points: &mut Vec<Point>, p: Point) {
    let far = points.last().is_none_or(|last| last.distance(p) >= THIN_MM);
    if far && points.len() < MAX_DRAWN {
        points.push(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn point() -> impl Strategy<Value = Point> {
        let coordinate = prop_oneof![-2000.0..2000.0, -1e150..1e150f64];
        (coordinate.clone(), coordinate).prop_map(|(x_mm, y_mm)| Point { x_mm, y_mm })
    }

    proptest! {
        /// The distance to a polyline is the least distance to its
        /// segments, however it is worked out, and finite for finite points.
        #[test]
        fn the_polyline_distance_is_the_least_segment_distance(
            path in proptest::collection::vec(point(), 2..12),
            p in point(),
        ) {
            let by_segment = path
                .windows(2)
                .map(|s| p.distance_to_segment(s[0], s[1]))
                .fold(f64::INFINITY, f64::min);
            let d = distance_to_polyline(&path, p);
            prop_assert!(d.is_finite());
            prop_assert!((d - by_segment).abs() <= 1e-9 * by_segment.max(1.0), "{d} against {by_segment}");
        }
    }

    fn at(x: f64, y: f64) -> Pose {
        Pose {
            x_mm: x,
            y_mm: y,
            theta_rad: 0.0,
        }
    }

    #[test]
    fn errors_are_distances_to_the_plan_and_to_the_truth() {
        let planned = vec![
            Point {
                x_mm: 0.0,
                y_mm: 0.0,
            },
            Point {
                x_mm: 100.0,
                y_mm: 0.0,
            },
        ];
        let mut recorder = PathRecorder::new(planned);
        // The estimate runs 3 mm off the plan, the truth 4 mm on the other side.
        for x in 0..=100 {
            let x = f64::from(x);
            recorder.record(at(x, 3.0), Some(at(x, -4.0)));
        }
        let analysis = recorder.finish();
        let tracking = analysis.tracking_error_mm.unwrap();
        assert!((tracking.mean - 3.0).abs() < 1e-9 && (tracking.max - 3.0).abs() < 1e-9);
        let path = analysis.path_error_mm.unwrap();
        assert!((path.rms - 4.0).abs() < 1e-9);
        assert!((analysis.estimate_error_mm.unwrap().max - 7.0).abs() < 1e-9);
        // Thinned to a point per 5 mm: 0, 5, …, 100.
        assert_eq!(analysis.estimated.len(), 21);
        assert_eq!(analysis.truth.len(), 21);
    }

    #[test]
    fn without_a_plan_or_truth_there_is_nothing_to_compare() {
        let mut recorder = PathRecorder::new(Vec::new());
        recorder.record(at(1.0, 1.0), None);
        let analysis = recorder.finish();
        assert_eq!(analysis.tracking_error_mm, None);
        assert_eq!(analysis.path_error_mm, None);
        assert_eq!(analysis.estimate_error_mm, None);
        assert!(analysis.truth.is_empty());
    }
}
