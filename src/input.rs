//! What the subcommands read from the user: the robot, the arena, the
//! simulated camera's optics, a real camera, a calibration, a dot target,
//! a duration. Any problem with them is the user's input (exit code 2).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Result;
use vl_core::{Arena, CameraModel, DotTarget, Point, RobotKind, RobotModel};
use vl_host::{CameraSource, FramePolicy};
use vl_sim::{Optics, OpticsPreset, Scheduled};

use crate::shipped::read_input;
use crate::{BadInput, named};

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
            (Some(radius), Some(base)) => model
                .resized(radius, base)
                .map_err(|e| BadInput(e.to_string()))?,
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
#[derive(clap::Args)]
pub(crate) struct OpticsArgs {
    /// Optics to start from: none (an ideal camera looking straight
    /// down), noisy (a cheap webcam: offset, blur, noise, uneven light) or
    /// realistic (noisy, a wide lens, 80 ms late, motion blur, 5 % lost).
    #[arg(long, value_parser = named::<OpticsPreset>(), default_value = "none")]
    optics: OpticsPreset,
    /// Image shift in px, as DX,DY (lens off the sensor's axis).
    #[arg(long, allow_hyphen_values = true)]
    lens_offset: Option<Point>,
    /// Gaussian blur, standard deviation in px.
    #[arg(long)]
    blur: Option<f64>,
    /// Per-pixel noise, standard deviation in grey levels.
    #[arg(long)]
    noise: Option<f64>,
    /// How much darker the bottom-right corner is (0–1).
    #[arg(long)]
    lighting: Option<f64>,
    /// How far the camera leans from looking straight down, degrees.
    #[arg(long, allow_hyphen_values = true)]
    tilt_deg: Option<f64>,
    /// The lens's radial distortion, as K1,K2 (radii in image widths;
    /// barrel distortion has K1 < 0).
    #[arg(long, allow_hyphen_values = true)]
    lens: Option<Point>,
    /// From a frame's exposure to its arrival, ms.
    #[arg(long)]
    delay_ms: Option<f64>,
    /// How long the shutter is open, ms (a moving robot smears).
    #[arg(long)]
    exposure_ms: Option<f64>,
    /// The share of frames lost (0–0.5).
    #[arg(long)]
    drop_rate: Option<f64>,
    /// The share of frames with the robot's marker partly hidden (0–0.5).
    #[arg(long)]
    occlusion_rate: Option<f64>,
}

impl OpticsArgs {
    /// The simulator's optics these flags ask for, checked.
    pub(crate) fn optics(&self, seed: u64) -> Result<Optics> {
        let mut optics = self.optics.optics(seed);
        if let Some(k) = self.lens {
            optics.distortion = vl_core::Distortion {
                k1: k.x_mm,
                k2: k.y_mm,
            };
        }
        optics.delay_s = self.delay_ms.map_or(optics.delay_s, |ms| ms / 1e3);
        optics.exposure_s = self.exposure_ms.map_or(optics.exposure_s, |ms| ms / 1e3);
        optics.drop_rate = self.drop_rate.unwrap_or(optics.drop_rate);
        optics.occlusion_rate = self.occlusion_rate.unwrap_or(optics.occlusion_rate);
        if let Some(p) = self.lens_offset {
            optics.lens_offset_px = [p.x_mm, p.y_mm];
        }
        optics.blur_px = self.blur.unwrap_or(optics.blur_px);
        optics.noise = self.noise.unwrap_or(optics.noise);
        optics.lighting_gradient = self.lighting.unwrap_or(optics.lighting_gradient);
        if let Some(deg) = self.tilt_deg {
            optics.tilt_rad = deg.to_radians();
        }
        optics.check().map_err(|e| BadInput(e.to_string()))?;
        Ok(optics)
    }
}

/// An image file in colour; one that cannot be read is the user's input.
pub(crate) fn load_rgb(path: &Path, what: &str) -> Result<image::RgbImage> {
    let image = vl_core::load_image(path)
        .map_err(|e| BadInput(format!("cannot read the {what} {}: {e}", path.display())))?;
    Ok(image.to_rgb8())
}

/// A shipped arena or an arena file; any problem with it is the user's input.
pub(crate) fn load_arena(name_or_path: &str) -> Result<Arena> {
    Ok(Arena::load(name_or_path).map_err(|e| BadInput(e.to_string()))?)
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
pub(crate) fn seconds(what: &str, s: f64) -> Result<Duration, BadInput> {
    if s.is_finite() && s > 0.0 && s <= 86_400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(BadInput(format!(
            "{what} must be a number of seconds from 0 to a day, not {s}"
        )))
    }
}

/// Which camera frames the Host sends (thesis appendix G).
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Frames {
    /// Every frame the camera takes: live video.
    EveryFrame,
    /// Only when the scene changes beyond the robot, when a Guest asks, and
    /// at least every --frame-interval; Guests draw the robot from its pose.
    OnChange,
}

#[derive(clap::Args)]
pub(crate) struct FramesArgs {
    #[arg(long, value_enum, default_value = "every-frame")]
    frames: Frames,
    /// With --frames on-change: the longest time between two frames, s.
    #[arg(long, default_value_t = 5.0)]
    frame_interval: f64,
}

impl FramesArgs {
    pub(crate) fn policy(&self) -> Result<FramePolicy> {
        Ok(match self.frames {
            Frames::EveryFrame => FramePolicy::EveryFrame,
            Frames::OnChange => FramePolicy::OnChange {
                max_interval: seconds("--frame-interval", self.frame_interval)?,
            },
        })
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
pub(crate) fn arena_from(name: &str, start: Option<vl_core::Pose>) -> Result<Arena> {
    let arena = load_arena(name)?;
    match start {
        Some(start) => Ok(arena
            .starting_at(start)
            .map_err(|e| BadInput(format!("--start: {e}")))?),
        None => Ok(arena),
    }
}
