//! The arena: the walled floor the robot drives on and the obstacles on it.
//! Host and Guest both use it: the simulator casts sensor rays into it, the
//! Host validates a definition's goal against it, the Guest draws it.

mod load;
pub(crate) mod map;
mod material;
mod shape;

use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use thiserror::Error;

pub use material::{Material, Obstacle};
pub use shape::{Shape, ShapeError};

use crate::{Point, Pose};

/// Where a sensor ray meets the first surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub distance_mm: f64,
    pub reflectivity: f64,
}

/// Why an arena description cannot be used.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum ArenaError {
    #[error("arena file: {0}")]
    Syntax(String),
    #[error("arena '{arena}': {why}")]
    Impossible { arena: String, why: String },
    #[error(
        "unknown arena '{0}' (shipped: {shipped}; or a .json file)",
        shipped = Arena::shipped().collect::<Vec<_>>().join(", ")
    )]
    Unknown(String),
    #[error("cannot read it: {0}")]
    Unreadable(String),
    /// A problem with an arena file, named with its path.
    #[error("{}: {problem}", path.display())]
    File {
        path: PathBuf,
        problem: Box<ArenaError>,
    },
}

/// Why an arena file's map image could not be had.
#[derive(Debug, thiserror::Error)]
pub enum MapImageError {
    #[error("cannot read the map image {image}: {why}")]
    Read {
        image: String,
        why: crate::ImageError,
    },
    #[error("cannot load '{0}' here: no directory to find it in")]
    NoDirectory(String),
}

/// A rectangular walled arena with its obstacles, where the robot starts,
/// and the goal the experiment suggests.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Arena {
    pub name: String,
    pub width_mm: f64,
    pub height_mm: f64,
    pub obstacles: Vec<Obstacle>,
    /// The walls around the floor.
    #[serde(default)]
    pub walls: Material,
    pub start: Pose,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<Point>,
}

impl Arena {
    /// Distance from `p` to the nearest wall or obstacle (0 inside one, or outside the walls).
    pub fn clearance(&self, p: Point) -> f64 {
        self.signed_clearance(p).max(0.0)
    }

    /// Signed distance from `p` to the nearest of the four walls alone.
    pub fn wall_clearance(&self, p: Point) -> f64 {
        p.x_mm
            .min(self.width_mm - p.x_mm)
            .min(p.y_mm)
            .min(self.height_mm - p.y_mm)
    }

    /// [`Arena::clearance`] with a sign: negative beyond a wall or inside
    /// an obstacle, by how far.
    pub fn signed_clearance(&self, p: Point) -> f64 {
        let walls = self.wall_clearance(p);
        self.obstacles
            .iter()
            .map(|o| o.shape.signed_distance(p))
            .fold(walls, f64::min)
    }

    /// Whether a disc of `radius_mm` at `p` touches nothing.
    pub fn is_free(&self, p: Point, radius_mm: f64) -> bool {
        self.clearance(p) > radius_mm
    }

    /// Distance along a ray from `o` to the first wall or obstacle it meets.
    pub fn ray(&self, o: Point, angle_rad: f64) -> f64 {
        self.ray_hit(o, angle_rad).distance_mm
    }

    /// The first wall or obstacle a ray from `o` meets: how far, and how
    /// well it reflects infrared.
    pub fn ray_hit(&self, o: Point, angle_rad: f64) -> Hit {
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
        let walls = Hit {
            distance_mm: wall(o.x_mm, dx, self.width_mm)
                .min(wall(o.y_mm, dy, self.height_mm))
                .max(0.0),
            reflectivity: self.walls.reflectivity,
        };
        self.obstacles
            .iter()
            .filter_map(|ob| {
                ob.shape.ray(o, angle_rad).map(|distance_mm| Hit {
                    distance_mm,
                    reflectivity: ob.material.reflectivity,
                })
            })
            .fold(
                walls,
                |a, b| if b.distance_mm < a.distance_mm { b } else { a },
            )
    }

    /// The same arena with the robot put at `start`, checked: where the
    /// simulated robot stands, and where a real one's dead reckoning begins.
    pub fn starting_at(mut self, start: Pose) -> Result<Arena, ArenaError> {
        self.start = start;
        self.check()?;
        Ok(self)
    }

    /// Whether the arena can exist: a positive size, valid shapes, a start
    /// and a goal on the floor.
    pub fn check(&self) -> Result<(), ArenaError> {
        let impossible = |why: String| ArenaError::Impossible {
            arena: self.name.clone(),
            why,
        };
        for (what, v) in [("width", self.width_mm), ("height", self.height_mm)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(impossible(format!(
                    "its {what} must be a positive number of mm, not {v}"
                )));
            }
        }
        for (i, o) in self.obstacles.iter().enumerate() {
            o.shape
                .check()
                .map_err(|e| e.to_string())
                .and_then(|()| o.material.check())
                .map_err(|why| impossible(format!("obstacle {i}: {why}")))?;
        }
        self.walls
            .check()
            .map_err(|why| impossible(format!("the walls: {why}")))?;
        let on_floor = |p: Point| {
            (0.0..=self.width_mm).contains(&p.x_mm) && (0.0..=self.height_mm).contains(&p.y_mm)
        };
        if !on_floor(self.start.point()) || !self.start.theta_rad.is_finite() {
            return Err(impossible("the start pose is not on the floor".into()));
        }
        if self.goal.is_some_and(|g| !on_floor(g)) {
            return Err(impossible("the goal is not on the floor".into()));
        }
        Ok(())
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
        let c = Shape::Circle {
            x_mm: 420.0,
            y_mm: 170.0,
            radius_mm: 45.0,
        };
        assert!((c.ray(p(300.0, 170.0), 0.0).unwrap() - 75.0).abs() < 1e-9);
        assert_eq!(c.ray(p(300.0, 170.0), std::f64::consts::PI), None);
    }

    #[test]
    fn shipped_starts_and_goals_are_free() {
        for a in Arena::shipped().map(|n| Arena::named(n).unwrap()) {
            assert!(a.is_free(a.start.point(), 35.0), "{}", a.name);
            assert!(a.goal.is_none_or(|g| a.is_free(g, 35.0)), "{}", a.name);
        }
    }

    fn shipped() -> impl Strategy<Value = Arena> {
        proptest::sample::select(Arena::shipped().collect::<Vec<_>>())
            .prop_map(|n| Arena::named(n).unwrap())
    }

    proptest! {
        /// A ray stops exactly at a surface: the point it reaches has zero
        /// clearance, and every point before it is free.
        #[test]
        fn ray_ends_on_a_surface(a in shipped(), fx in 0.001f64..0.999, fy in 0.001f64..0.999, angle in -3.2f64..3.2) {
            let (x, y) = (fx * a.width_mm, fy * a.height_mm);
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
