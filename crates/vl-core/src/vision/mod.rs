//! Vision on the overhead camera's frames: grey conversion, binarisation
//! (fixed or Otsu), connected components with their moments and Hu
//! invariants, and the robot's pose from its markers.
//!
//! Conventions follow OpenCV so results can be checked against it: grey is
//! ITU-R 601 luma in 15-bit fixed point, a fixed threshold keeps pixels
//! brighter than it, components are numbered in raster order of their first
//! pixel, and moments use integer pixel coordinates (column x, row y, y
//! down).

mod components;
mod floor;
mod robot;
mod target;
mod threshold;

use std::time::Instant;

use image::RgbImage;
use serde::Serialize;
use vl_report::table::{Report, Table};

use crate::{CameraModel, Named};

pub use components::{Centroid, Component, components, label};
pub use floor::{Look, arena_of, changed_cells, look};
pub use robot::{RobotPose, is_robot, robot_pose};
pub use target::{DotTarget, TargetError};
pub use threshold::{Mask, Threshold, ThresholdError, binarise, grey, otsu};

/// Which pixels touch: edges only, or edges and corners.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Connectivity {
    Four,
    Eight,
}

impl Named for Connectivity {
    const KIND: &'static str = "connectivity";
    const ALL: &'static [Self] = &[Connectivity::Four, Connectivity::Eight];

    fn id(self) -> &'static str {
        match self {
            Connectivity::Four => "4",
            Connectivity::Eight => "8",
        }
    }
}

crate::named_by_id!(Connectivity);

/// Everything the camera tells: the threshold used, each component, and
/// the robot's pose if one component is the robot.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Scene {
    pub threshold: u8,
    pub components: Vec<Component>,
    pub robot: Option<RobotPose>,
}

/// The whole pipeline on one frame: grey, threshold (Otsu's unless given),
/// 8-connected components, robot pose.
pub fn inspect(image: &RgbImage, threshold: Threshold, invert: bool) -> Scene {
    let grey = grey(image);
    let threshold = match threshold {
        Threshold::Otsu => otsu(&grey),
        Threshold::Level(level) => level,
    };
    let mask = binarise(&grey, threshold, invert);
    let (components, _) = components(&mask, Connectivity::Eight);
    let robot = components.iter().find(|c| is_robot(c)).and_then(robot_pose);
    Scene {
        threshold,
        components,
        robot,
    }
}

/// How fast [`inspect`] and [`look`] run on one frame.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct VisionBench {
    pub width: u32,
    pub height: u32,
    pub runs: u32,
    /// The whole pipeline: every component's moments and Hu invariants.
    pub ms_per_frame: f64,
    /// What the Host does with every frame in the loop: locate the robot
    /// (and label the floor for the map).
    pub look_ms_per_frame: f64,
}

/// Times the whole pipeline and the in-loop look on `frame` over `runs`
/// runs each (dark objects on a light floor, Otsu's threshold), after one
/// untimed run that warms caches and the allocator.
pub fn bench(frame: &RgbImage, runs: u32) -> VisionBench {
    let runs = runs.max(1);
    let per_frame = |work: &dyn Fn()| {
        work();
        let started = Instant::now();
        for _ in 0..runs {
            work();
        }
        started.elapsed().as_secs_f64() * 1e3 / f64::from(runs)
    };
    let camera = CameraModel::overhead(
        f64::from(frame.width()),
        f64::from(frame.height()),
        frame.width(),
        15.0,
    );
    let ms_per_frame = per_frame(&|| {
        std::hint::black_box(inspect(std::hint::black_box(frame), Threshold::Otsu, true));
    });
    let look_ms_per_frame = per_frame(&|| {
        std::hint::black_box(look(std::hint::black_box(frame), &camera));
    });
    VisionBench {
        width: frame.width(),
        height: frame.height(),
        runs,
        ms_per_frame,
        look_ms_per_frame,
    }
}

impl Report for Scene {
    fn table(&self) -> Table {
        let mut table = Table::columns(&["label", "area", "centroid", "bbox", "angle °", "hu1"])
            .title(format!("threshold {}", self.threshold));
        for c in &self.components {
            let [x, y, w, h] = c.bbox;
            table.row(vec![
                c.label.to_string(),
                c.area.to_string(),
                format!("({:.1}, {:.1})", c.centroid.x, c.centroid.y),
                format!("{x},{y} {w}×{h}"),
                format!("{:.1}", c.orientation_rad.to_degrees()),
                format!("{:.6}", c.hu[0]),
            ]);
        }
        table.note(match self.robot {
            Some(r) => format!(
                "robot at ({:.1}, {:.1}) px, heading {:.1}°",
                r.x,
                r.y,
                r.theta.to_degrees()
            ),
            None => "no robot found".to_owned(),
        })
    }
}

impl Report for VisionBench {
    fn table(&self) -> Table {
        Table::pairs([
            ("frame", format!("{}×{} px", self.width, self.height)),
            ("runs", self.runs.to_string()),
            (
                "per frame",
                format!(
                    "{:.3} ms (grey, Otsu, 8-connected components, moments, Hu, robot)",
                    self.ms_per_frame
                ),
            ),
            (
                "in the loop",
                format!(
                    "{:.3} ms (locate the robot, label the floor: the Host's look at each frame)",
                    self.look_ms_per_frame
                ),
            ),
        ])
    }
}
