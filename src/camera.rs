//! `vl camera …`: calibrating the lab's overhead camera, so a tilted or
//! off-centre camera maps its pixels to floor millimetres.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use serde::Serialize;
use vl_core::{Calibration, CameraModel, ImageSize, Point, PointPair};
use vl_sim::SimCalibration;

use crate::input::{load_arena, load_rgb, load_target, positive, read_json, real_camera};
use crate::report::{Report, Table, emit};
use crate::{BadInput, bad_input};
use vl_host::CameraSource;

#[derive(Subcommand)]
pub(crate) enum CameraCommand {
    /// Fit the camera's floor-to-image map from floor points whose pixels
    /// are known: a file of point pairs, a picture of a dot target, or the
    /// simulated camera looking at one. Writes the calibration `vl host
    /// --camera-calibration` reads.
    Calibrate(Box<CalibrateArgs>),
    /// List the webcams on this machine (Video4Linux2) and the formats,
    /// sizes and rates each captures in that `vl host --camera v4l2:…` reads.
    List {
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args)]
pub(crate) struct CalibrateArgs {
    /// A JSON list of pairs: [{"floor_mm": [x, y], "pixel": [column, row]}, …],
    /// at least four, no three on a line.
    #[arg(long, conflicts_with_all = ["image", "sim"], requires = "image_size")]
    points: Option<PathBuf>,
    /// The size of the camera's images the points were read from, WxH.
    #[arg(long)]
    image_size: Option<ImageSize>,
    /// A picture of a dot target laid on the floor (with --target).
    #[arg(long, conflicts_with = "sim", requires = "target")]
    image: Option<PathBuf>,
    /// Or a frame from the lab's camera looking at the target (with
    /// --target): http://… (an MJPEG stream) or v4l2:/dev/videoN[,…].
    #[arg(long, conflicts_with_all = ["sim", "image", "points"], requires = "target", value_parser = str::parse::<CameraSource>)]
    camera: Option<CameraSource>,
    /// The dot target as JSON: {"cols", "rows", "first_mm": {"x_mm", "y_mm"},
    /// "spacing_mm": [x, y], "radius_mm"}; its rows must run along the
    /// image's rows.
    #[arg(long)]
    target: Option<PathBuf>,
    /// Calibrate the simulated camera: render a dot target on the arena's
    /// floor through the optics below, find it, fit, and compare with the
    /// camera the simulator really used.
    #[arg(long)]
    sim: bool,
    /// The arena whose floor the simulated camera looks at.
    #[arg(long, default_value = "navigation")]
    arena: String,
    /// The simulated camera's image width, px.
    #[arg(long, default_value_t = 640)]
    width: u32,
    #[command(flatten)]
    optics: crate::options::OpticsArgs,
    /// Seed of the simulated camera's noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The frame rate the calibrated camera captures at.
    #[arg(long, default_value_t = 15.0)]
    fps: f64,
    /// Where to write the calibration (JSON).
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

/// What calibration found.
#[derive(Serialize)]
struct Calibrated {
    #[serde(flatten)]
    calibration: Calibration,
    /// Against the simulator's true camera, when it was simulated.
    #[serde(skip_serializing_if = "Option::is_none")]
    truth_max_px: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    written_to: Option<PathBuf>,
}

impl Report for Calibrated {
    fn table(&self) -> Table {
        let mut table = self.calibration.table();
        if let Some(truth) = self.truth_max_px {
            table.row(vec![
                "off the true camera".into(),
                format!("{truth:.3} px at worst"),
            ]);
        }
        if let Some(path) = &self.written_to {
            table = table.note(format!("wrote {}", path.display()));
        }
        table
    }
}

pub(crate) fn run(command: CameraCommand) -> Result<ExitCode> {
    match command {
        CameraCommand::Calibrate(args) => calibrate(*args),
        #[cfg(not(target_os = "linux"))]
        CameraCommand::List { .. } => {
            anyhow::bail!(BadInput(
                "webcams are read through Video4Linux2, which only Linux has".into()
            ))
        }
        #[cfg(target_os = "linux")]
        CameraCommand::List { json } => {
            let devices = vl_host::list_devices().context("cannot list the video devices")?;
            emit(&devices, json)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn calibrate(args: CalibrateArgs) -> Result<ExitCode> {
    positive("--fps", args.fps)?;
    let bad = |e: vl_core::CalibrationError| BadInput(e.to_string());
    let (calibration, truth_max_px) = if let Some(path) = &args.points {
        let size = args.image_size.expect("clap requires --image-size");
        let pairs: Vec<PointPair> = read_json(
            path,
            "points file (a JSON list of {\"floor_mm\": [x, y], \"pixel\": [col, row]})",
        )?;
        let pairs: Vec<(Point, [f64; 2])> = pairs.into_iter().map(Into::into).collect();
        (
            CameraModel::calibrated(size.width, size.height, args.fps, &pairs).map_err(bad)?,
            None,
        )
    } else if let Some(path) = &args.image {
        let target = load_target(args.target.as_ref().expect("clap requires --target"))?;
        let image = load_rgb(path, "image")?;
        (target.calibrate(&image, args.fps).map_err(bad)?, None)
    } else if let Some(driver) = args.camera {
        let target = load_target(args.target.as_ref().expect("clap requires --target"))?;
        let floor = load_arena(&args.arena)?;
        let mut camera = real_camera(driver, None, &floor)?
            .ok_or_else(|| BadInput("--camera: give a real camera, http://… or v4l2:…".into()))?;
        let frame = camera.grab().context("no frame from the camera")?;
        (target.calibrate(&frame.image, args.fps).map_err(bad)?, None)
    } else if args.sim {
        let arena = load_arena(&args.arena)?;
        let optics = args.optics.optics(args.seed).map_err(bad_input)?;
        let nominal =
            CameraModel::overhead(arena.width_mm, arena.height_mm, args.width.max(1), args.fps);
        let SimCalibration {
            calibration,
            truth_max_px,
        } = vl_sim::calibrate(&nominal, &optics, arena.width_mm, arena.height_mm).map_err(bad)?;
        (calibration, Some(truth_max_px))
    } else {
        return Err(BadInput(
            "say what to calibrate from: --points FILE --image-size WxH, --image PHOTO --target FILE, --camera URL --target FILE, or --sim"
                .into(),
        )
        .into());
    };
    if let Some(path) = &args.output {
        let text = serde_json::to_string_pretty(&calibration)?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    emit(
        &Calibrated {
            calibration,
            truth_max_px,
            written_to: args.output,
        },
        args.json,
    )?;
    Ok(ExitCode::SUCCESS)
}
