//! The arena: the walled floor the robot drives on and the obstacles on it.
//! Host and Guest both use it: the simulator casts sensor rays into it, the
//! Host validates a definition's goal against it, the Guest draws it.

use serde::{Deserialize, Serialize};

use crate::robot::{Point, Pose};

/// An obstacle on the arena floor, in mm in the arena frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum Obstacle {
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
}

/// A rectangular walled arena with its obstacles, where the robot starts,
/// and the goal the experiment suggests.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arena {
    pub name: String,
    pub width_mm: f64,
    pub height_mm: f64,
    pub obstacles: Vec<Obstacle>,
    pub start: Pose,
    pub goal: Option<Point>,
}

impl Obstacle {
    /// The corners (bottom-left, top-right) of the smallest box holding the obstacle.
    pub fn bounds(&self) -> (Point, Point) {
        match *self {
            Obstacle::Rect {
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
            Obstacle::Circle {
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
        }
    }

    /// Distance from `p` to the obstacle's boundary; 0 inside it.
    pub fn distance(&self, p: Point) -> f64 {
        match *self {
            Obstacle::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            } => {
                let dx = (x_mm - p.x_mm).max(p.x_mm - (x_mm + width_mm)).max(0.0);
                let dy = (y_mm - p.y_mm).max(p.y_mm - (y_mm + height_mm)).max(0.0);
                dx.hypot(dy)
            }
            Obstacle::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => ((p.x_mm - x_mm).hypot(p.y_mm - y_mm) - radius_mm).max(0.0),
        }
    }

    /// Distance along the ray from `o` in direction (cos a, sin a) to the
    /// obstacle, if the ray hits it (0 when `o` is inside).
    pub fn ray(&self, o: Point, angle_rad: f64) -> Option<f64> {
        let (dy, dx) = angle_rad.sin_cos();
        match *self {
            Obstacle::Rect {
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
            Obstacle::Circle {
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
        }
    }
}

impl Arena {
    /// Distance from `p` to the nearest wall or obstacle (0 inside one, or outside the walls).
    pub fn clearance(&self, p: Point) -> f64 {
        let walls = p
            .x_mm
            .min(self.width_mm - p.x_mm)
            .min(p.y_mm)
            .min(self.height_mm - p.y_mm)
            .max(0.0);
        self.obstacles
            .iter()
            .map(|o| o.distance(p))
            .fold(walls, f64::min)
    }

    /// Whether a disc of `radius_mm` at `p` touches nothing.
    pub fn is_free(&self, p: Point, radius_mm: f64) -> bool {
        self.clearance(p) > radius_mm
    }

    /// Distance along a ray from `o` to the first wall or obstacle it meets.
    pub fn ray(&self, o: Point, angle_rad: f64) -> f64 {
        let (dy, dx) = angle_rad.sin_cos();
        let wall = |o: f64, d: f64, hi: f64| {
            if d > 1e-12 {
                (hi - o) / d
            } else if d < -1e-12 {
                -o / d
            } else {
                f64::INFINITY
            }
        };
        let walls = wall(o.x_mm, dx, self.width_mm)
            .min(wall(o.y_mm, dy, self.height_mm))
            .max(0.0);
        self.obstacles
            .iter()
            .filter_map(|ob| ob.ray(o, angle_rad))
            .fold(walls, f64::min)
    }

    /// The thesis's navigation experiment: a robot, a goal and several
    /// obstacles between them, on an 800 × 600 mm floor.
    pub fn navigation() -> Self {
        Arena {
            name: "navigation".into(),
            width_mm: 800.0,
            height_mm: 600.0,
            obstacles: vec![
                Obstacle::Rect {
                    x_mm: 250.0,
                    y_mm: 0.0,
                    width_mm: 60.0,
                    height_mm: 230.0,
                },
                Obstacle::Rect {
                    x_mm: 480.0,
                    y_mm: 380.0,
                    width_mm: 60.0,
                    height_mm: 220.0,
                },
                Obstacle::Circle {
                    x_mm: 420.0,
                    y_mm: 170.0,
                    radius_mm: 45.0,
                },
                Obstacle::Circle {
                    x_mm: 180.0,
                    y_mm: 430.0,
                    radius_mm: 35.0,
                },
            ],
            start: Pose {
                x_mm: 100.0,
                y_mm: 120.0,
                theta_rad: 0.0,
            },
            goal: Some(Point {
                x_mm: 680.0,
                y_mm: 470.0,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn p(x_mm: f64, y_mm: f64) -> Point {
        Point { x_mm, y_mm }
    }

    #[test]
    fn rays_hit_walls_and_obstacles() {
        let a = Arena::navigation();
        // From the start, looking +x, the first thing met is the box at x = 250.
        assert!((a.ray(p(100.0, 120.0), 0.0) - 150.0).abs() < 1e-9);
        // Looking down, the floor wall at y = 0.
        assert!((a.ray(p(100.0, 120.0), -std::f64::consts::FRAC_PI_2) - 120.0).abs() < 1e-9);
        // Straight at the circle at (420, 170) r 45 from (300, 170): 75 mm.
        let c = Obstacle::Circle {
            x_mm: 420.0,
            y_mm: 170.0,
            radius_mm: 45.0,
        };
        assert!((c.ray(p(300.0, 170.0), 0.0).unwrap() - 75.0).abs() < 1e-9);
        assert_eq!(c.ray(p(300.0, 170.0), std::f64::consts::PI), None);
    }

    #[test]
    fn the_navigation_start_and_goal_are_free() {
        let a = Arena::navigation();
        assert!(a.is_free(a.start.point(), 35.0));
        assert!(a.is_free(a.goal.unwrap(), 35.0));
    }

    proptest! {
        /// A ray stops exactly at a surface: the point it reaches has zero
        /// clearance, and every point before it is free.
        #[test]
        fn ray_ends_on_a_surface(x in 1.0f64..799.0, y in 1.0f64..599.0, angle in -3.2f64..3.2) {
            let a = Arena::navigation();
            let o = p(x, y);
            prop_assume!(a.clearance(o) > 1e-6);
            let d = a.ray(o, angle);
            let hit = p(x + d * angle.cos(), y + d * angle.sin());
            prop_assert!(a.clearance(hit) < 1e-6);
            let before = p(x + 0.99 * d * angle.cos(), y + 0.99 * d * angle.sin());
            prop_assert!(a.clearance(before) > 0.0);
        }
    }
}
