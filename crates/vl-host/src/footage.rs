//! A camera that plays recorded lab footage back: the images of a
//! directory, in name order, at the camera's frame rate, round and round.
//! It stands in for the overhead camera when replaying a session, and
//! behaves as a real one does when its footage goes away: `grab` fails, the
//! lab says the camera is offline, and it answers again when the images are
//! back.

use std::path::{Path, PathBuf};
use std::time::Instant;

use image::RgbImage;
use vl_core::{CameraModel, load_image};

use crate::drivers::{Camera, CameraError, Captured, believed};

/// Image files a footage directory may hold.
const EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

pub struct FootageCamera {
    dir: PathBuf,
    frames: Vec<PathBuf>,
    next: usize,
    model: CameraModel,
}

impl FootageCamera {
    /// Footage from `dir`, seen through `model`, or (without one) as by a
    /// camera looking straight down on a `floor_mm` floor at `fps`.
    pub fn open(
        dir: &Path,
        model: Option<CameraModel>,
        floor_mm: (f64, f64),
        fps: f64,
    ) -> Result<FootageCamera, CameraError> {
        let frames = list(dir)?;
        let first = frames.first().ok_or_else(|| {
            CameraError::Setup(format!(
                "no footage in {}: it holds no .png or .jpg images",
                dir.display()
            ))
        })?;
        let image = read(first)?;
        let model = believed(model, floor_mm, image.width(), fps);
        Ok(FootageCamera {
            dir: dir.to_owned(),
            frames,
            next: 0,
            model,
        })
    }
}

/// The images in `dir`, by name.
fn list(dir: &Path) -> Result<Vec<PathBuf>, CameraError> {
    let entries = std::fs::read_dir(dir).map_err(|e| {
        CameraError::Setup(format!("cannot read the footage in {}: {e}", dir.display()))
    })?;
    let mut frames: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| EXTENSIONS.contains(&x.to_ascii_lowercase().as_str()))
        })
        .collect();
    frames.sort();
    Ok(frames)
}

fn read(path: &Path) -> Result<RgbImage, CameraError> {
    load_image(path)
        .map(|image| image.to_rgb8())
        .map_err(|e| CameraError::Frame(format!("cannot read the frame {}: {e}", path.display())))
}

impl Camera for FootageCamera {
    fn model(&self) -> CameraModel {
        self.model
    }

    fn grab(&mut self) -> Result<Captured, CameraError> {
        if self.next >= self.frames.len() {
            // Round again, over what the directory holds now.
            self.frames = list(&self.dir)?;
            self.next = 0;
            if self.frames.is_empty() {
                return Err(CameraError::Silent(format!(
                    "the footage in {} is gone",
                    self.dir.display()
                )));
            }
        }
        let image = read(&self.frames[self.next])?;
        self.next += 1;
        let (w, h) = (self.model.width_px, self.model.height_px);
        if image.dimensions() != (w, h) {
            return Err(CameraError::Frame(format!(
                "frame {} is {}×{} px, the camera {w}×{h}",
                self.frames[self.next - 1].display(),
                image.width(),
                image.height()
            )));
        }
        Ok(Captured {
            image,
            taken: Instant::now(),
        })
    }
}
