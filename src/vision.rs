//! `vl vision …`: what the overhead camera's frames tell, for calibrating
//! the lab and checking the vision pipeline.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use clap::Subcommand;
use image::RgbImage;
use serde::Serialize;
use vl_core::vision::{Scene, inspect};

use crate::BadInput;

#[derive(Subcommand)]
pub enum VisionCommand {
    /// Threshold a frame, list its connected components (8-connected) with
    /// their moments, and find the robot by its markers.
    Inspect {
        image: PathBuf,
        /// otsu, or a grey level 0–255: foreground is brighter than it.
        #[arg(long, default_value = "otsu")]
        threshold: String,
        /// Foreground is darker instead (dark objects on a light floor).
        #[arg(long)]
        invert: bool,
        #[arg(long)]
        json: bool,
    },
    /// Time the whole pipeline on one frame, in-process, over many runs.
    Bench {
        image: PathBuf,
        #[arg(long, default_value_t = 200)]
        runs: u32,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(command: VisionCommand) -> Result<ExitCode> {
    match command {
        VisionCommand::Inspect {
            image,
            threshold,
            invert,
            json,
        } => {
            let frame = load(&image)?;
            let threshold = match threshold.as_str() {
                "otsu" => None,
                level => Some(level.parse::<u8>().map_err(|_| {
                    BadInput(format!(
                        "--threshold must be 'otsu' or a grey level 0–255, not '{level}'"
                    ))
                })?),
            };
            let scene = inspect(&frame, threshold, invert);
            if json {
                println!("{}", serde_json::to_string_pretty(&scene)?);
            } else {
                print_scene(&scene);
            }
            Ok(ExitCode::SUCCESS)
        }
        VisionCommand::Bench { image, runs, json } => {
            let frame = load(&image)?;
            let runs = runs.max(1);
            // One untimed run warms caches and the allocator.
            std::hint::black_box(inspect(&frame, None, true));
            let started = Instant::now();
            for _ in 0..runs {
                std::hint::black_box(inspect(std::hint::black_box(&frame), None, true));
            }
            let report = BenchReport {
                width: frame.width(),
                height: frame.height(),
                runs,
                ms_per_frame: started.elapsed().as_secs_f64() * 1e3 / f64::from(runs),
            };
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                println!(
                    "{}×{} px, {} runs: {:.3} ms per frame (grey, Otsu, 8-connected components, moments, Hu, robot)",
                    report.width, report.height, report.runs, report.ms_per_frame
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

#[derive(Serialize)]
struct BenchReport {
    width: u32,
    height: u32,
    runs: u32,
    ms_per_frame: f64,
}

fn load(path: &Path) -> Result<RgbImage> {
    Ok(image::open(path)
        .map_err(|e| BadInput(format!("cannot read the image {}: {e}", path.display())))?
        .to_rgb8())
}

fn print_scene(scene: &Scene) {
    println!("threshold {}", scene.threshold);
    println!(
        "{:>5} {:>8} {:>16} {:>20} {:>9} {:>12}",
        "label", "area", "centroid", "bbox", "angle °", "hu1"
    );
    for c in &scene.components {
        println!(
            "{:>5} {:>8} {:>16} {:>20} {:>9.1} {:>12.6}",
            c.label,
            c.area,
            format!("({:.1}, {:.1})", c.centroid.x, c.centroid.y),
            format!("{:?}", c.bbox),
            c.orientation_rad.to_degrees(),
            c.hu[0]
        );
    }
    match scene.robot {
        Some(r) => println!(
            "robot at ({:.1}, {:.1}) px, heading {:.1}°",
            r.x,
            r.y,
            r.theta.to_degrees()
        ),
        None => println!("no robot found"),
    }
}
