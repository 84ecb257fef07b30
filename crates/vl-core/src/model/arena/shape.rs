//! The shapes obstacles and virtual obstacles take on the arena floor, in
//! mm in the arena frame, and the geometry the simulator, the planner and
//! the Host's guards ask of them: bounds, distance, rays.

use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::Point;
use crate::syntax::{SyntaxError, parse_numbers};

/// A shape that cannot exist.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeError {
    #[error("{0} not a finite position")]
    NotFinite(&'static str),
    #[error("its {what} must be a positive number, not {value}")]
    NotPositive { what: &'static str, value: f64 },
    #[error("a polygon needs at least 3 vertices, this one has {0}")]
    TooFewVertices(usize),
    #[error("the polygon encloses no area")]
    NoArea,
}

/// A shape on the arena floor, in mm in the arena frame: an obstacle's
/// geometry, or a virtual obstacle an experiment adds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum Shape {
    /// An axis-aligned box; (x, y) is its bottom-left corner.
    Rect {
        x_mm: f64,
        y_mm: f64,
        width_mm: f64,
        height_mm: f64,
    },
    Circle {
        x_mm: f64,
        y_mm: f64,
        radius_mm: f64,
    },
    /// A simple polygon, vertices in order (either winding).
    Polygon { points: Vec<Point> },
}

impl Shape {
    /// The corners (bottom-left, top-right) of the smallest box holding the obstacle.
    pub fn bounds(&self) -> (Point, Point) {
        match *self {
            Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            } => (
                Point { x_mm, y_mm },
                Point {
                    x_mm: x_mm + width_mm,
                    y_mm: y_mm + height_mm,
                },
            ),
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => (
                Point {
                    x_mm: x_mm - radius_mm,
                    y_mm: y_mm - radius_mm,
                },
                Point {
                    x_mm: x_mm + radius_mm,
                    y_mm: y_mm + radius_mm,
                },
            ),
            Shape::Polygon { ref points } => points.iter().fold(
                (
                    Point {
                        x_mm: f64::INFINITY,
                        y_mm: f64::INFINITY,
                    },
                    Point {
                        x_mm: f64::NEG_INFINITY,
                        y_mm: f64::NEG_INFINITY,
                    },
                ),
                |(lo, hi), p| {
                    (
                        Point {
                            x_mm: lo.x_mm.min(p.x_mm),
                            y_mm: lo.y_mm.min(p.y_mm),
                        },
                        Point {
                            x_mm: hi.x_mm.max(p.x_mm),
                            y_mm: hi.y_mm.max(p.y_mm),
                        },
                    )
                },
            ),
        }
    }

    /// Whether the shape is one that can exist: finite, positive sizes, a
    /// polygon of at least three vertices enclosing some area.
    pub fn check(&self) -> Result<(), ShapeError> {
        let finite = |v: f64| v.is_finite();
        let positive = |what: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(ShapeError::NotPositive { what, value })
            }
        };
        match *self {
            Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            } => {
                if !(finite(x_mm) && finite(y_mm)) {
                    return Err(ShapeError::NotFinite("its corner is"));
                }
                positive("width", width_mm)?;
                positive("height", height_mm)
            }
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => {
                if !(finite(x_mm) && finite(y_mm)) {
                    return Err(ShapeError::NotFinite("its centre is"));
                }
                positive("radius", radius_mm)
            }
            Shape::Polygon { ref points } => {
                if points.len() < 3 {
                    return Err(ShapeError::TooFewVertices(points.len()));
                }
                if !points.iter().all(|p| finite(p.x_mm) && finite(p.y_mm)) {
                    return Err(ShapeError::NotFinite("a polygon vertex is"));
                }
                if polygon_area(points).abs() < 1e-9 {
                    return Err(ShapeError::NoArea);
                }
                Ok(())
            }
        }
    }

    /// Distance from `p` to the obstacle's boundary; 0 inside it.
    pub fn distance(&self, p: Point) -> f64 {
        self.signed_distance(p).max(0.0)
    }

    /// Signed distance from `p` to the obstacle's boundary: positive
    /// outside, negative inside by how deep `p` is. The safety layer needs
    /// the sign: a pose estimate already past a face must still see that
    /// going deeper is worse and coming out is better.
    pub fn signed_distance(&self, p: Point) -> f64 {
        match *self {
            Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            } => {
                let dx = (x_mm - p.x_mm).max(p.x_mm - (x_mm + width_mm));
                let dy = (y_mm - p.y_mm).max(p.y_mm - (y_mm + height_mm));
                if dx <= 0.0 && dy <= 0.0 {
                    dx.max(dy)
                } else {
                    dx.max(0.0).hypot(dy.max(0.0))
                }
            }
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => (p.x_mm - x_mm).hypot(p.y_mm - y_mm) - radius_mm,
            Shape::Polygon { ref points } => {
                let edge = edges(points)
                    .map(|(a, b)| p.distance_to_segment(a, b))
                    .fold(f64::INFINITY, f64::min);
                if contains(points, p) { -edge } else { edge }
            }
        }
    }

    /// How many vertices describe the shape: what the cost of measuring
    /// distances to it grows with (a box or a circle counts as 4).
    pub fn vertices(&self) -> usize {
        match self {
            Shape::Rect { .. } | Shape::Circle { .. } => 4,
            Shape::Polygon { points } => points.len(),
        }
    }

    /// Distance along the ray from `o` in direction (cos a, sin a) to the
    /// obstacle, if the ray hits it (0 when `o` is inside).
    pub fn ray(&self, o: Point, angle_rad: f64) -> Option<f64> {
        let (dy, dx) = angle_rad.sin_cos();
        match *self {
            Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            } => {
                // Slab method: intersect the ray's parameter ranges inside each axis band.
                let slab = |o: f64, d: f64, lo: f64, hi: f64| -> Option<(f64, f64)> {
                    if d.abs() < 1e-12 {
                        (lo..=hi)
                            .contains(&o)
                            .then_some((f64::NEG_INFINITY, f64::INFINITY))
                    } else {
                        let (a, b) = ((lo - o) / d, (hi - o) / d);
                        Some((a.min(b), a.max(b)))
                    }
                };
                let (ax, bx) = slab(o.x_mm, dx, x_mm, x_mm + width_mm)?;
                let (ay, by) = slab(o.y_mm, dy, y_mm, y_mm + height_mm)?;
                let (enter, exit) = (ax.max(ay), bx.min(by));
                (enter <= exit && exit >= 0.0).then_some(enter.max(0.0))
            }
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => {
                let (fx, fy) = (o.x_mm - x_mm, o.y_mm - y_mm);
                let b = fx * dx + fy * dy;
                let c = fx * fx + fy * fy - radius_mm * radius_mm;
                if c <= 0.0 {
                    return Some(0.0);
                }
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                (t >= 0.0).then_some(t)
            }
            Shape::Polygon { ref points } => {
                if contains(points, o) {
                    return Some(0.0);
                }
                edges(points)
                    .filter_map(|(a, b)| ray_segment(o, dx, dy, a, b))
                    .fold(None, |best: Option<f64>, t| {
                        Some(best.map_or(t, |b| b.min(t)))
                    })
            }
        }
    }
}

/// `rect:X,Y,W,H` (bottom-left corner), `circle:X,Y,R` or
/// `polygon:X,Y;X,Y;…`, in mm: how a shape is written on a command line.
impl FromStr for Shape {
    type Err = SyntaxError;

    fn from_str(text: &str) -> Result<Shape, SyntaxError> {
        let form = |expected, got: &str| SyntaxError::Form {
            expected,
            got: got.to_owned(),
        };
        let (kind, numbers) = text
            .split_once(':')
            .ok_or_else(|| form("expected rect:…, circle:… or polygon:…", text))?;
        let shape = match kind {
            "rect" => match *parse_numbers(numbers)?.as_slice() {
                [x_mm, y_mm, width_mm, height_mm] => Shape::Rect {
                    x_mm,
                    y_mm,
                    width_mm,
                    height_mm,
                },
                _ => return Err(form("rect needs X,Y,W,H", numbers)),
            },
            "circle" => match *parse_numbers(numbers)?.as_slice() {
                [x_mm, y_mm, radius_mm] => Shape::Circle {
                    x_mm,
                    y_mm,
                    radius_mm,
                },
                _ => return Err(form("circle needs X,Y,R", numbers)),
            },
            "polygon" => Shape::Polygon {
                points: crate::model::robot::parse_points(numbers)?,
            },
            other => {
                return Err(SyntaxError::Unknown {
                    kind: "shape",
                    got: other.to_owned(),
                    expected: "use rect, circle or polygon",
                });
            }
        };
        shape.check()?;
        Ok(shape)
    }
}

/// A polygon's edges, closing the last vertex back to the first.
fn edges(points: &[Point]) -> impl Iterator<Item = (Point, Point)> + '_ {
    points
        .iter()
        .zip(points.iter().cycle().skip(1))
        .map(|(a, b)| (*a, *b))
}

/// Signed area (positive counter-clockwise), by the shoelace formula.
fn polygon_area(points: &[Point]) -> f64 {
    edges(points)
        .map(|(a, b)| a.x_mm * b.y_mm - b.x_mm * a.y_mm)
        .sum::<f64>()
        / 2.0
}

/// Whether `p` lies inside the polygon (even–odd rule).
fn contains(points: &[Point], p: Point) -> bool {
    edges(points).fold(false, |inside, (a, b)| {
        let crosses = (a.y_mm > p.y_mm) != (b.y_mm > p.y_mm)
            && p.x_mm < (b.x_mm - a.x_mm) * (p.y_mm - a.y_mm) / (b.y_mm - a.y_mm) + a.x_mm;
        inside != crosses
    })
}

/// Where the ray o + t·(dx, dy), t ≥ 0, meets segment ab, if it does.
fn ray_segment(o: Point, dx: f64, dy: f64, a: Point, b: Point) -> Option<f64> {
    let (ex, ey) = (b.x_mm - a.x_mm, b.y_mm - a.y_mm);
    let denom = dx * ey - dy * ex;
    if denom.abs() < 1e-12 {
        return None;
    }
    let (wx, wy) = (a.x_mm - o.x_mm, a.y_mm - o.y_mm);
    let t = (wx * ey - wy * ex) / denom;
    let u = (wx * dy - wy * dx) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x_mm: f64, y_mm: f64) -> Point {
        Point { x_mm, y_mm }
    }

    #[test]
    fn polygons_have_inside_edges_and_rays() {
        let triangle = Shape::Polygon {
            points: vec![p(0.0, 0.0), p(100.0, 0.0), p(0.0, 100.0)],
        };
        assert_eq!(triangle.distance(p(10.0, 10.0)), 0.0);
        assert!((triangle.distance(p(50.0, -20.0)) - 20.0).abs() < 1e-9);
        assert!(
            (triangle
                .ray(p(50.0, -20.0), std::f64::consts::FRAC_PI_2)
                .unwrap()
                - 20.0)
                .abs()
                < 1e-9
        );
        assert_eq!(triangle.ray(p(200.0, 200.0), 0.0), None);
        assert_eq!(triangle.check(), Ok(()));
        let line = Shape::Polygon {
            points: vec![p(0.0, 0.0), p(1.0, 1.0), p(2.0, 2.0)],
        };
        assert!(line.check().unwrap_err().to_string().contains("no area"));
        let two = Shape::Polygon {
            points: vec![p(0.0, 0.0), p(1.0, 1.0)],
        };
        assert!(
            two.check()
                .unwrap_err()
                .to_string()
                .contains("at least 3 vertices")
        );
    }

    #[test]
    fn shapes_are_written_as_kind_and_numbers() {
        assert_eq!(
            "circle:1,2,3".parse(),
            Ok(Shape::Circle {
                x_mm: 1.0,
                y_mm: 2.0,
                radius_mm: 3.0
            })
        );
        assert_eq!(
            "rect:0,0,10,5".parse::<Shape>().map(|s| s.bounds().1),
            Ok(p(10.0, 5.0))
        );
        let triangle: Shape = "polygon:0,0;10,0;0,10".parse().unwrap();
        assert_eq!(triangle.distance(p(1.0, 1.0)), 0.0);
        assert!(
            "circle:1,2,-3"
                .parse::<Shape>()
                .unwrap_err()
                .to_string()
                .contains("radius")
        );
        assert!(
            "square:1,2,3"
                .parse::<Shape>()
                .unwrap_err()
                .to_string()
                .contains("unknown shape")
        );
        assert!(
            "rect:1,2"
                .parse::<Shape>()
                .unwrap_err()
                .to_string()
                .contains("X,Y,W,H")
        );
        assert!(
            "circle:1,x,3"
                .parse::<Shape>()
                .unwrap_err()
                .to_string()
                .contains("'x'")
        );
    }

    proptest::proptest! {
        /// The signed distance is the distance outside, minus the depth
        /// inside, and never changes faster than the point moves: what lets
        /// the safety layer tell deeper from shallower past a face.
        #[test]
        fn signed_distance_is_distance_with_a_sign(
            kind in 0usize..3,
            x in -50.0f64..150.0, y in -50.0f64..150.0,
            dx in -5.0f64..5.0, dy in -5.0f64..5.0,
        ) {
            let shape = match kind {
                0 => Shape::Rect { x_mm: 10.0, y_mm: 20.0, width_mm: 60.0, height_mm: 30.0 },
                1 => Shape::Circle { x_mm: 50.0, y_mm: 50.0, radius_mm: 25.0 },
                _ => Shape::Polygon {
                    points: vec![p(0.0, 0.0), p(100.0, 0.0), p(100.0, 100.0), p(50.0, 40.0), p(0.0, 100.0)],
                },
            };
            let (a, b) = (p(x, y), p(x + dx, y + dy));
            let (signed, unsigned) = (shape.signed_distance(a), shape.distance(a));
            if unsigned > 0.0 {
                proptest::prop_assert!((signed - unsigned).abs() < 1e-9, "{} vs {}", signed, unsigned);
            } else {
                proptest::prop_assert!(signed <= 1e-9);
            }
            let moved = (shape.signed_distance(b) - signed).abs();
            proptest::prop_assert!(moved <= a.distance(b) + 1e-9, "moved {} for {}", moved, a.distance(b));
        }
    }
}
