//! The arena: the walled floor the robot drives on and the obstacles on it.
//! Host and Guest both use it: the simulator casts sensor rays into it, the
//! Host validates a definition's goal against it, the Guest draws it.

use image::GrayImage;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::robot::{Point, Pose};

/// The arenas that ship with `vl`, by name, with the map image one names.
const SHIPPED: [(&str, &str, &[u8]); 4] = [
    ("navigation", include_str!("../arenas/navigation.json"), b""),
    ("corridor", include_str!("../arenas/corridor.json"), b""),
    ("open", include_str!("../arenas/open.json"), b""),
    (
        "maze",
        include_str!("../arenas/maze.json"),
        include_bytes!("../arenas/maze.png"),
    ),
];

/// A shape on the arena floor, in mm in the arena frame: an obstacle's
/// geometry, or a virtual obstacle an experiment adds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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

/// What an obstacle's surface is like to the robot's infrared sensors and
/// to the overhead camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Fraction of the infrared a white surface returns (K-Team's
    /// calibration is for white): 0.01 for matt black, 1 for white.
    #[serde(default = "Material::white_ir")]
    pub reflectivity: f64,
    /// sRGB colour the camera sees from above.
    #[serde(default = "Material::dark")]
    pub colour: [u8; 3],
}

impl Material {
    fn white_ir() -> f64 {
        1.0
    }

    fn dark() -> [u8; 3] {
        [48, 50, 58]
    }

    fn check(&self) -> Result<(), String> {
        if self.reflectivity.is_finite() && (0.0..=1.0).contains(&self.reflectivity) {
            Ok(())
        } else {
            Err(format!(
                "its reflectivity must be between 0 and 1, not {}",
                self.reflectivity
            ))
        }
    }
}

impl Default for Material {
    /// Dark tops with white sides: how the lab's wooden blocks look.
    fn default() -> Self {
        Material {
            reflectivity: Material::white_ir(),
            colour: Material::dark(),
        }
    }
}

/// An obstacle: a shape and what it is made of.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Obstacle {
    #[serde(flatten)]
    pub shape: Shape,
    #[serde(flatten)]
    pub material: Material,
}

impl From<Shape> for Obstacle {
    fn from(shape: Shape) -> Self {
        Obstacle {
            shape,
            material: Material::default(),
        }
    }
}

/// A top-view image of the arena: its dark pixels are obstacles.
#[derive(Debug, Deserialize)]
struct MapImage {
    image: String,
    mm_per_px: f64,
    #[serde(default = "MapImage::mid_grey")]
    threshold: u8,
}

impl MapImage {
    fn mid_grey() -> u8 {
        128
    }
}

/// The pixels of `image` darker than `threshold`, as few rectangles (mm, in
/// the ROS map frame): runs of dark pixels along each row, merged with the
/// identical run of the row below.
fn dark_boxes(image: &GrayImage, threshold: u8, mm_per_px: f64) -> Vec<Shape> {
    let (w, h) = image.dimensions();
    let mut done = Vec::new();
    // Runs still growing downwards: (first column, end column) → first row.
    let mut open: std::collections::BTreeMap<(u32, u32), u32> = Default::default();
    let close = |(c0, c1): (u32, u32), r0: u32, r1: u32| Shape::Rect {
        x_mm: f64::from(c0) * mm_per_px,
        y_mm: f64::from(h - r1) * mm_per_px,
        width_mm: f64::from(c1 - c0) * mm_per_px,
        height_mm: f64::from(r1 - r0) * mm_per_px,
    };
    for r in 0..=h {
        let mut runs = Vec::new();
        let mut c = 0;
        while r < h && c < w {
            if image.get_pixel(c, r).0[0] < threshold {
                let start = c;
                while c < w && image.get_pixel(c, r).0[0] < threshold {
                    c += 1;
                }
                runs.push((start, c));
            }
            c += 1;
        }
        let mut next = std::collections::BTreeMap::new();
        for run in runs {
            next.insert(run, open.remove(&run).unwrap_or(r));
        }
        for (run, r0) in std::mem::replace(&mut open, next) {
            done.push(close(run, r0, r));
        }
    }
    done
}

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
}

/// A rectangular walled arena with its obstacles, where the robot starts,
/// and the goal the experiment suggests.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arena {
    pub name: String,
    pub width_mm: f64,
    pub height_mm: f64,
    pub obstacles: Vec<Obstacle>,
    /// The walls around the floor.
    #[serde(default)]
    pub walls: Material,
    pub start: Pose,
    pub goal: Option<Point>,
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
    pub fn check(&self) -> Result<(), String> {
        let finite = |v: f64| v.is_finite();
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("its {what} must be a positive number, not {v}"))
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
                    return Err("its corner is not a finite position".into());
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
                    return Err("its centre is not a finite position".into());
                }
                positive("radius", radius_mm)
            }
            Shape::Polygon { ref points } => {
                if points.len() < 3 {
                    return Err(format!(
                        "a polygon needs at least 3 vertices, this one has {}",
                        points.len()
                    ));
                }
                if !points.iter().all(|p| finite(p.x_mm) && finite(p.y_mm)) {
                    return Err("a polygon vertex is not a finite position".into());
                }
                if polygon_area(points).abs() < 1e-9 {
                    return Err("the polygon encloses no area".into());
                }
                Ok(())
            }
        }
    }

    /// Distance from `p` to the obstacle's boundary; 0 inside it.
    pub fn distance(&self, p: Point) -> f64 {
        match *self {
            Shape::Rect {
                x_mm,
                y_mm,
                width_mm,
                height_mm,
            } => {
                let dx = (x_mm - p.x_mm).max(p.x_mm - (x_mm + width_mm)).max(0.0);
                let dy = (y_mm - p.y_mm).max(p.y_mm - (y_mm + height_mm)).max(0.0);
                dx.hypot(dy)
            }
            Shape::Circle {
                x_mm,
                y_mm,
                radius_mm,
            } => ((p.x_mm - x_mm).hypot(p.y_mm - y_mm) - radius_mm).max(0.0),
            Shape::Polygon { ref points } => {
                if contains(points, p) {
                    return 0.0;
                }
                edges(points)
                    .map(|(a, b)| segment_distance(p, a, b))
                    .fold(f64::INFINITY, f64::min)
            }
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

fn segment_distance(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.x_mm - a.x_mm, b.y_mm - a.y_mm);
    let len2 = dx * dx + dy * dy;
    let t = if len2 == 0.0 {
        0.0
    } else {
        (((p.x_mm - a.x_mm) * dx + (p.y_mm - a.y_mm) * dy) / len2).clamp(0.0, 1.0)
    };
    (p.x_mm - (a.x_mm + t * dx)).hypot(p.y_mm - (a.y_mm + t * dy))
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
            .map(|o| o.shape.distance(p))
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

    /// The thesis's navigation experiment: a robot, a goal and several
    /// obstacles between them, on an 800 × 600 mm floor.
    pub fn navigation() -> Self {
        Arena::named("navigation").expect("the navigation arena ships with vl")
    }

    /// A shipped arena by name: navigation, corridor, open or maze.
    pub fn named(name: &str) -> Option<Arena> {
        let (_, text, map) = SHIPPED.iter().find(|(n, ..)| *n == name)?;
        let load = |_: &str| {
            image::load_from_memory(map)
                .map(|i| i.to_luma8())
                .map_err(|e| e.to_string())
        };
        Some(Arena::from_json_with(text, load).expect("shipped arenas are valid"))
    }

    /// The names of the shipped arenas.
    pub fn shipped() -> impl Iterator<Item = &'static str> {
        SHIPPED.iter().map(|(n, ..)| *n)
    }

    /// An arena from its JSON description, checked to be one that can exist.
    /// A description with a `map` (a top-view image) is refused: its image
    /// must be loaded with [`Arena::from_json_with`].
    pub fn from_json(text: &str) -> Result<Arena, ArenaError> {
        Arena::from_json_with(text, |image| {
            Err(format!(
                "cannot load '{image}' here: no directory to find it in"
            ))
        })
    }

    /// An arena from its JSON description, where an optional
    /// `"map": {"image": FILE, "mm_per_px": S, "threshold": T}` adds the
    /// image's dark pixels (grey below T, default 128) as obstacles, and
    /// gives the arena the image's size unless the file states one.
    /// `load` reads the named image.
    pub fn from_json_with(
        text: &str,
        load: impl FnOnce(&str) -> Result<GrayImage, String>,
    ) -> Result<Arena, ArenaError> {
        let syntax = |e: serde_json::Error| ArenaError::Syntax(e.to_string());
        let mut value: serde_json::Value = serde_json::from_str(text).map_err(syntax)?;
        let map = value.as_object_mut().and_then(|o| o.remove("map"));
        if let Some(map) = map {
            let map: MapImage =
                serde_json::from_value(map).map_err(|e| ArenaError::Syntax(format!("map: {e}")))?;
            let name = value["name"].as_str().unwrap_or("unnamed").to_owned();
            let impossible = |why: String| ArenaError::Impossible {
                arena: name.clone(),
                why,
            };
            if !(map.mm_per_px.is_finite() && map.mm_per_px > 0.0) {
                return Err(impossible(format!(
                    "the map's scale must be a positive number of mm per pixel, not {}",
                    map.mm_per_px
                )));
            }
            let image = load(&map.image).map_err(impossible)?;
            let object = value.as_object_mut().expect("a map key means an object");
            let s = map.mm_per_px;
            object
                .entry("width_mm")
                .or_insert((f64::from(image.width()) * s).into());
            object
                .entry("height_mm")
                .or_insert((f64::from(image.height()) * s).into());
            let found = dark_boxes(&image, map.threshold, s);
            let obstacles = object
                .entry("obstacles")
                .or_insert(serde_json::Value::Array(Vec::new()));
            if let Some(list) = obstacles.as_array_mut() {
                for shape in found {
                    list.push(serde_json::to_value(Obstacle::from(shape)).map_err(syntax)?);
                }
            }
        }
        let arena: Arena = serde_json::from_value(value).map_err(syntax)?;
        arena.check()?;
        Ok(arena)
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
        assert!(line.check().unwrap_err().contains("no area"));
        let two = Shape::Polygon {
            points: vec![p(0.0, 0.0), p(1.0, 1.0)],
        };
        assert!(two.check().unwrap_err().contains("at least 3 vertices"));
    }

    #[test]
    fn arena_files_are_checked() {
        for name in Arena::shipped() {
            assert!(Arena::named(name).is_some(), "{name}");
        }
        assert!(matches!(
            Arena::from_json("{ \"name\": "),
            Err(ArenaError::Syntax(_))
        ));
        let mut bad = Arena::navigation();
        bad.obstacles.push(
            Shape::Circle {
                x_mm: 1.0,
                y_mm: 1.0,
                radius_mm: -3.0,
            }
            .into(),
        );
        let text = serde_json::to_string(&bad).unwrap();
        let e = Arena::from_json(&text).unwrap_err();
        assert!(
            e.to_string()
                .contains("obstacle 4: its radius must be a positive number"),
            "{e}"
        );
    }

    #[test]
    fn maps_become_obstacles() {
        let maze = Arena::named("maze").unwrap();
        assert_eq!((maze.width_mm, maze.height_mm), (800.0, 600.0));
        // The bar drawn over columns 40–47, rows 0–79 of the 120-row image.
        assert_eq!(maze.clearance(p(220.0, 400.0)), 0.0);
        assert!((maze.clearance(p(190.0, 400.0)) - 10.0).abs() < 1e-9);
        assert!(maze.is_free(maze.start.point(), 35.0));
        let scale = r#"{"name": "m", "map": {"image": "x.png", "mm_per_px": 0}, "start": {"x_mm": 1, "y_mm": 1, "theta_rad": 0}}"#;
        let e = Arena::from_json_with(scale, |_| Ok(GrayImage::new(4, 4))).unwrap_err();
        assert!(e.to_string().contains("scale must be a positive"), "{e}");
        let e = Arena::from_json(&scale.replace("0}", "2}")).unwrap_err();
        assert!(e.to_string().contains("cannot load 'x.png'"), "{e}");
    }

    fn shipped() -> impl Strategy<Value = Arena> {
        proptest::sample::select(Arena::shipped().collect::<Vec<_>>())
            .prop_map(|n| Arena::named(n).unwrap())
    }

    proptest! {
        /// A map's rectangles cover exactly its dark pixels.
        #[test]
        fn dark_boxes_cover_the_dark_pixels(w in 1u32..12, h in 1u32..12, seed in any::<u64>()) {
            let mut state = seed | 1;
            let image = GrayImage::from_fn(w, h, |_, _| {
                state ^= state << 13; state ^= state >> 7; state ^= state << 17;
                image::Luma([if state % 3 == 0 { 20 } else { 200 }])
            });
            let boxes = dark_boxes(&image, 128, 2.0);
            for (c, r, px) in image.enumerate_pixels() {
                let centre = p((f64::from(c) + 0.5) * 2.0, (f64::from(h - r) - 0.5) * 2.0);
                let covered = boxes.iter().filter(|b| b.distance(centre) == 0.0).count();
                prop_assert_eq!(covered, usize::from(px.0[0] < 128), "pixel ({}, {})", c, r);
            }
        }

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
