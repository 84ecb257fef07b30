//! What the subcommands read from the user: the robot, the arena, the
//! simulated camera's optics, a real camera, a calibration, a dot target,
//! a duration. Any problem with them is the user's input (exit code 2).

use std::path::{Path, PathBuf};
#[cfg(feature = "host")]
use std::time::Duration;

use anyhow::Result;
#[cfg(feature = "host")]
use vl_core::CameraModel;
use vl_core::{Arena, DotTarget, RobotKind, RobotModel};
#[cfg(feature = "host")]
use vl_host::CameraSource;
use vl_sim::Scheduled;

use crate::shipped::read_input;
use crate::{BadInput, bad_input, named};

/// Which robot to simulate, and its size if not the stock one.
#[derive(clap::Args)]
pub(crate) struct RobotArgs {
    #[arg(long, value_parser = named::<RobotKind>(), default_value = "khepera-ii")]
    robot: RobotKind,
    /// Build the robot with this body radius, mm (sensors move out with it).
    #[arg(long, requires = "wheel_base_mm")]
    radius_mm: Option<f64>,
    /// … and this distance between its wheels, mm.
    #[arg(long, requires = "radius_mm")]
    wheel_base_mm: Option<f64>,
    /// Or a whole robot model from a JSON file (`vl khepera characterise` writes one).
    #[arg(long, conflicts_with_all = ["robot", "radius_mm"])]
    robot_model: Option<PathBuf>,
}

impl RobotArgs {
    pub(crate) fn model(&self) -> Result<RobotModel> {
        if let Some(file) = &self.robot_model {
            return load_robot_model(file);
        }
        let model = self.robot.model();
        Ok(match (self.radius_mm, self.wheel_base_mm) {
            (Some(radius), Some(base)) => model.resized(radius, base).map_err(bad_input)?,
            _ => model,
        })
    }
}

/// A robot model file; any problem with it is the user's input.
pub(crate) fn load_robot_model(path: &Path) -> Result<RobotModel> {
    let text = read_input(path)?;
    Ok(RobotModel::from_json(&text).map_err(|e| BadInput(format!("{}: {e}", path.display())))?)
}

/// How the simulated camera departs from an ideal one: a preset, and any
/// of its figures changed.
/// An image file in colour; one that cannot be read is the user's input.
pub(crate) fn load_rgb(path: &Path, what: &str) -> Result<image::RgbImage> {
    let image = vl_core::load_image(path)
        .map_err(|e| BadInput(format!("cannot read the {what} {}: {e}", path.display())))?;
    Ok(image.to_rgb8())
}

/// A shipped arena or an arena file; any problem with it is the user's input.
pub(crate) fn load_arena(name_or_path: &str) -> Result<Arena> {
    Ok(Arena::load(name_or_path).map_err(bad_input)?)
}

/// Reads `path` as JSON of a `kind` of file, naming the kind and what
/// writes it when it is not one.
pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path, kind: &str) -> Result<T> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| BadInput(format!("cannot read the {kind} {}: {e}", path.display())))?;
    Ok(serde_json::from_str(&text)
        .map_err(|e| BadInput(format!("{} is not a {kind}: {e}", path.display())))?)
}

/// The camera a calibration file (what `vl camera calibrate -o` writes) holds.
#[cfg(feature = "host")]
pub(crate) fn load_calibration(path: &Path) -> Result<CameraModel> {
    let kind = "calibration file (as `vl camera calibrate -o` writes)";
    Ok(read_json::<vl_core::Calibration>(path, kind)?.camera)
}

/// A dot target described in `path`.
pub(crate) fn load_target(path: &Path) -> Result<DotTarget> {
    let target: DotTarget = read_json(path, "dot target description")?;
    target
        .check()
        .map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
    Ok(target)
}

#[cfg(feature = "host")]
/// The real camera `source` names (see [`CameraSource::open`]); footage
/// that cannot be read is the user's input.
pub(crate) fn real_camera(
    source: CameraSource,
    calibration: Option<CameraModel>,
    arena: &Arena,
) -> Result<Option<Box<dyn vl_host::Camera>>> {
    let footage = matches!(source, CameraSource::Replay(_));
    source.open(calibration, arena).map_err(|e| {
        if footage {
            BadInput(e.to_string()).into()
        } else {
            anyhow::Error::new(e).context("cannot read the camera")
        }
    })
}

/// A figure the user gave that must be a positive number.
pub(crate) fn positive(what: &str, v: f64) -> Result<f64, BadInput> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(BadInput(format!(
            "{what} must be a positive number, not {v}"
        )))
    }
}

/// A duration the user gave, in seconds: above 0 and at most a day.
#[cfg(feature = "host")]
pub(crate) fn seconds(what: &str, s: f64) -> Result<Duration, BadInput> {
    if s.is_finite() && s > 0.0 && s <= 86_400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(BadInput(format!(
            "{what} must be a number of seconds from 0 to a day, not {s}"
        )))
    }
}

/// What people do in the simulated lab while it runs.
#[derive(clap::Args)]
pub(crate) struct SceneArgs {
    /// At T s on the lab's clock, put an obstacle down (`T:place:SHAPE`,
    /// e.g. 3:place:rect:400,100,40,40) or hold a hand over the robot
    /// (`T:cover:SECONDS`); repeatable.
    #[arg(long = "scene-event", value_parser = str::parse::<Scheduled>)]
    pub(crate) events: Vec<Scheduled>,
}

/// The arena `name` (shipped, or a JSON file), started at `start` if given.
#[cfg(feature = "host")]
pub(crate) fn arena_from(name: &str, start: Option<vl_core::Pose>) -> Result<Arena> {
    let arena = load_arena(name)?;
    match start {
        Some(start) => Ok(arena
            .starting_at(start)
            .map_err(|e| BadInput(format!("--start: {e}")))?),
        None => Ok(arena),
    }
}
