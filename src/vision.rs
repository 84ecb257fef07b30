//! `vl vision …`: what the overhead camera's frames tell, for calibrating
//! the lab and checking the vision pipeline.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use image::RgbImage;
use vl_core::{Scene, Threshold, VisionBench, inspect};

use crate::BadInput;
use crate::report::{Report, Table, emit};

#[derive(Subcommand)]
pub(crate) enum VisionCommand {
    /// Threshold a frame, list its connected components (8-connected) with
    /// their moments, and find the robot by its markers.
    Inspect {
        image: PathBuf,
        /// otsu, or a grey level 0–255: foreground is brighter than it.
        #[arg(long, default_value = "otsu")]
        threshold: Threshold,
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

pub(crate) fn run(command: VisionCommand) -> Result<ExitCode> {
    match command {
        VisionCommand::Inspect {
            image,
            threshold,
            invert,
            json,
        } => emit(&inspect(&load(&image)?, threshold, invert), json)?,
        VisionCommand::Bench { image, runs, json } => {
            emit(&vl_core::bench_vision(&load(&image)?, runs), json)?
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn load(path: &Path) -> Result<RgbImage> {
    Ok(vl_core::load_image(path)
        .map_err(|e| BadInput(format!("cannot read the image {}: {e}", path.display())))?
        .to_rgb8())
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
