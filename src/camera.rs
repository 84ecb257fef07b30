//! `vl camera …`: calibrating the lab's overhead camera, so a tilted or
//! off-centre camera maps its pixels to floor millimetres.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use serde::{Deserialize, Serialize};
use vl_core::{Calibration, CameraModel, Point};
use vl_sim::SimCalibration;

use crate::BadInput;
use crate::input::{
    CameraDriver, OpticsArgs, load_arena, load_target, parse_camera, read_json, real_camera,
};
use crate::report::{Report, Table, emit};

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

/// The webcams found.
#[cfg(target_os = "linux")]
#[derive(Serialize)]
#[serde(transparent)]
struct Webcams(Vec<vl_host::DeviceInfo>);

#[cfg(target_os = "linux")]
impl Report for Webcams {
    fn table(&self) -> Table {
        if self.0.is_empty() {
            return Table::pairs([]).note("no video capture devices (/dev/video*) on this machine");
        }
        let mut table = Table::columns(&["device", "camera", "format", "size", "frames/s"]);
        for device in &self.0 {
            let name = format!("{} ({})", device.card, device.driver);
            if device.modes.is_empty() {
                table.row(vec![
                    device.path.display().to_string(),
                    name.clone(),
                    "no MJPEG or YUYV".into(),
                    String::new(),
                    String::new(),
                ]);
            }
            for mode in &device.modes {
                let fps: Vec<String> = mode.fps.iter().map(|f| format!("{f:.0}")).collect();
                table.row(vec![
                    device.path.display().to_string(),
                    name.clone(),
                    mode.format.to_string(),
                    format!("{}×{}", mode.width, mode.height),
                    fps.join(", "),
                ]);
            }
        }
        table.note("use one as: vl host --camera v4l2:DEVICE,WIDTHxHEIGHT,RATEfps,FORMAT")
    }
}

#[derive(Args)]
pub(crate) struct CalibrateArgs {
    /// A JSON list of pairs: [{"floor_mm": [x, y], "pixel": [column, row]}, …],
    /// at least four, no three on a line.
    #[arg(long, conflicts_with_all = ["image", "sim"], requires = "image_size")]
    points: Option<PathBuf>,
    /// The size of the camera's images the points were read from, WxH.
    #[arg(long, value_parser = parse_size)]
    image_size: Option<(u32, u32)>,
    /// A picture of a dot target laid on the floor (with --target).
    #[arg(long, conflicts_with = "sim", requires = "target")]
    image: Option<PathBuf>,
    /// Or a frame from the lab's camera looking at the target (with
    /// --target): http://… (an MJPEG stream) or v4l2:/dev/videoN[,…].
    #[arg(long, conflicts_with_all = ["sim", "image", "points"], requires = "target", value_parser = parse_camera)]
    camera: Option<CameraDriver>,
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
    optics: OpticsArgs,
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

fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', '×'])
        .ok_or_else(|| format!("'{text}' is not WxH, e.g. 640x480"))?;
    let px = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| (1..=vl_core::MAX_IMAGE_SIDE).contains(&v))
            .ok_or_else(|| {
                format!(
                    "'{v}' is not a size in pixels from 1 to {}",
                    vl_core::MAX_IMAGE_SIDE
                )
            })
    };
    Ok((px(w)?, px(h)?))
}

/// One known point: where it is on the floor and where the image shows it.
#[derive(Deserialize)]
struct PointPair {
    floor_mm: [f64; 2],
    pixel: [f64; 2],
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
        let camera = &self.calibration.camera;
        let fit = &self.calibration.reprojection;
        let mut rows = vec![
            (
                "image",
                format!(
                    "{} × {} px at {} fps",
                    camera.width_px, camera.height_px, camera.fps
                ),
            ),
            ("points", fit.points.to_string()),
            ("reprojection rms", format!("{:.3} px", fit.rms_px)),
            ("reprojection max", format!("{:.3} px", fit.max_px)),
            (
                "scale at the centre",
                format!("{:.3} mm per px", camera.mm_per_px()),
            ),
            (
                "lens distortion",
                format!(
                    "k1 {:+.4}, k2 {:+.4}",
                    camera.distortion().k1,
                    camera.distortion().k2
                ),
            ),
        ];
        if let Some(truth) = self.truth_max_px {
            rows.push(("off the true camera", format!("{truth:.3} px at worst")));
        }
        let mut table = Table::pairs(rows).title("camera calibration");
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
            emit(&Webcams(devices), json)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn calibrate(args: CalibrateArgs) -> Result<ExitCode> {
    if !(args.fps.is_finite() && args.fps > 0.0) {
        return Err(BadInput(format!("--fps must be a positive number, not {}", args.fps)).into());
    }
    let bad = |e: vl_core::CalibrationError| BadInput(e.to_string());
    let (calibration, truth_max_px) = if let Some(path) = &args.points {
        let (w, h) = args.image_size.expect("clap requires --image-size");
        let pairs: Vec<PointPair> = read_json(
            path,
            "points file (a JSON list of {\"floor_mm\": [x, y], \"pixel\": [col, row]})",
        )?;
        let pairs: Vec<(Point, [f64; 2])> = pairs
            .into_iter()
            .map(|p| {
                let [x_mm, y_mm] = p.floor_mm;
                (Point { x_mm, y_mm }, p.pixel)
            })
            .collect();
        (
            CameraModel::calibrated(w, h, args.fps, &pairs).map_err(bad)?,
            None,
        )
    } else if let Some(path) = &args.image {
        let target = load_target(args.target.as_ref().expect("clap requires --target"))?;
        let image = vl_core::load_image(path)
            .map_err(|e| BadInput(format!("cannot read the image {}: {e}", path.display())))?
            .to_rgb8();
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
        let optics = args.optics.optics(args.seed)?;
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
