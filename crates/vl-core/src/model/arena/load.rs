//! Where arenas come from: the ones that ship inside `vl`, and JSON files
//! a lab writes (optionally naming a top-view image whose dark pixels are
//! obstacles).

use std::path::{Path, PathBuf};

use image::GrayImage;

use super::MapImageError;
use super::map::{MapImage, dark_boxes};
use crate::{Arena, ArenaError, Obstacle};

/// The arenas that ship with `vl`, by name, with the map image one names.
const SHIPPED: [(&str, &str, &[u8]); 4] = [
    (
        "navigation",
        include_str!("../../../arenas/navigation.json"),
        b"",
    ),
    (
        "corridor",
        include_str!("../../../arenas/corridor.json"),
        b"",
    ),
    ("open", include_str!("../../../arenas/open.json"), b""),
    (
        "maze",
        include_str!("../../../arenas/maze.json"),
        include_bytes!("../../../arenas/maze.png"),
    ),
];

impl Arena {
    /// The thesis's navigation experiment: a robot, a goal and several
    /// obstacles between them, on an 800 × 600 mm floor.
    pub fn navigation() -> Self {
        Arena::named("navigation").expect("the navigation arena ships with vl")
    }

    /// A shipped arena by name: navigation, corridor, open or maze.
    pub fn named(name: &str) -> Option<Arena> {
        let (_, text, map) = SHIPPED.iter().find(|(n, ..)| *n == name)?;
        let load = |_: &str| {
            crate::decode_image(map, None)
                .map(|i| i.to_luma8())
                .map_err(|why| MapImageError::Read {
                    image: name.to_owned(),
                    why,
                })
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
            Err(MapImageError::NoDirectory(image.to_owned()))
        })
    }

    /// An arena from its JSON description, where an optional
    /// `"map": {"image": FILE, "mm_per_px": S, "threshold": T}` adds the
    /// image's dark pixels (grey below T, default 128) as obstacles, and
    /// gives the arena the image's size unless the file states one.
    /// `load` reads the named image.
    pub fn from_json_with(
        text: &str,
        load: impl FnOnce(&str) -> Result<GrayImage, MapImageError>,
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
            let image = load(&map.image).map_err(|e| impossible(e.to_string()))?;
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

    /// A shipped arena by name, or else an arena file (JSON) by path, its
    /// map image named relative to the file.
    pub fn load(name_or_path: &str) -> Result<Arena, ArenaError> {
        if let Some(arena) = Arena::named(name_or_path) {
            return Ok(arena);
        }
        let path = Path::new(name_or_path);
        if !(path.extension().is_some_and(|e| e == "json") || path.exists()) {
            return Err(ArenaError::Unknown(name_or_path.to_owned()));
        }
        let in_file = |problem: ArenaError| ArenaError::File {
            path: path.to_owned(),
            problem: Box::new(problem),
        };
        let text = std::fs::read_to_string(path)
            .map_err(|e| in_file(ArenaError::Unreadable(e.to_string())))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let load = |image: &str| {
            let file: PathBuf = dir.join(image);
            crate::load_image(&file)
                .map(|i| i.to_luma8())
                .map_err(|why| MapImageError::Read {
                    image: file.display().to_string(),
                    why,
                })
        };
        Arena::from_json_with(&text, load).map_err(in_file)
    }

    /// A shipped map image by the name of its arena (`maze`), in grey.
    pub fn shipped_map(name: &str) -> Option<GrayImage> {
        let (_, _, map) = SHIPPED.iter().find(|(n, ..)| *n == name)?;
        crate::decode_image(map, None).ok().map(|i| i.to_luma8())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Point, Shape};

    fn p(x_mm: f64, y_mm: f64) -> Point {
        Point { x_mm, y_mm }
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

    #[test]
    fn arenas_load_by_name_or_from_a_file() {
        assert_eq!(
            Arena::load("corridor"),
            Ok(Arena::named("corridor").unwrap())
        );
        let e = Arena::load("juggling").unwrap_err().to_string();
        assert!(e.contains("unknown arena 'juggling' (shipped: navigation, corridor, open, maze; or a .json file)"), "{e}");
        let dir = std::env::temp_dir().join(format!("vl-arena-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("mine.json");
        let mut mine = Arena::navigation();
        mine.name = "mine".into();
        std::fs::write(&file, serde_json::to_string(&mine).unwrap()).unwrap();
        assert_eq!(Arena::load(file.to_str().unwrap()), Ok(mine));
        std::fs::write(&file, "{").unwrap();
        let e = Arena::load(file.to_str().unwrap()).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}: arena file: ", file.display())),
            "{e}"
        );
        let e = Arena::load(dir.join("none.json").to_str().unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.json: cannot read it:"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
