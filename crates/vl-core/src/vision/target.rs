//! Calibrating the camera from a picture of a dot target: a sheet of dark
//! dots at known floor points. The dots are found by the same binarisation
//! and components as everything else the camera sees, matched to the
//! target's points in reading order, and the camera's homography fitted.

use image::RgbImage;
use serde::{Deserialize, Serialize};

use super::{Connectivity, binarise, components, grey, otsu};
use crate::Point;
use crate::model::camera::{Calibration, CameraModel};
use crate::model::homography::CalibrationError;

/// The most dots a target has along a side.
const MAX_DOTS_A_SIDE: u32 = 100;

/// A target description no target fits.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TargetError {
    #[error("a target has 1 to {MAX_DOTS_A_SIDE} columns and rows of dots, not {0} × {1}")]
    Dots(u32, u32),
    #[error("a target's radius, spacing and first dot must be finite and its sizes positive")]
    Sizes,
}

/// A calibration target: `cols` × `rows` dark dots laid on the floor, with
/// the target's rows running roughly along the image's rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct DotTarget {
    pub cols: u32,
    pub rows: u32,
    /// The bottom-left dot's centre, mm.
    pub first_mm: Point,
    /// From one dot to the next, along x and along y, mm.
    pub spacing_mm: [f64; 2],
    pub radius_mm: f64,
}

impl DotTarget {
    /// A grid of 16 mm dots (big enough that their edges' pixels average
    /// out) spread over a `width_mm` × `height_mm` floor as far out to the
    /// corners, where a lens bends the image most, as leaves each dot clear
    /// of the image's edge: at most 13 × 10, 3.5 radii apart or more.
    pub fn spread_over(width_mm: f64, height_mm: f64) -> DotTarget {
        let radius_mm = 16.0;
        let margin = |side: f64| 0.03 * side + radius_mm;
        let count = |side: f64, most: u32| {
            let span = side - 2.0 * margin(side);
            ((span / (3.5 * radius_mm)).floor() as u32 + 1).clamp(2, most)
        };
        let (cols, rows) = (count(width_mm, 13), count(height_mm, 10));
        DotTarget {
            cols,
            rows,
            first_mm: Point {
                x_mm: margin(width_mm),
                y_mm: margin(height_mm),
            },
            spacing_mm: [
                (width_mm - 2.0 * margin(width_mm)) / f64::from(cols - 1),
                (height_mm - 2.0 * margin(height_mm)) / f64::from(rows - 1),
            ],
            radius_mm,
        }
    }

    /// Whether `vl` can look for it: 1 to 100 columns and
    /// rows, and positive, finite sizes at a finite place.
    pub fn check(&self) -> Result<(), TargetError> {
        let sized = |v: f64| v.is_finite() && v > 0.0;
        let dots = 1..=MAX_DOTS_A_SIDE;
        if !(dots.contains(&self.cols) && dots.contains(&self.rows)) {
            return Err(TargetError::Dots(self.cols, self.rows));
        }
        let [sx, sy] = self.spacing_mm;
        if !(sized(self.radius_mm)
            && sized(sx)
            && sized(sy)
            && self.first_mm.x_mm.is_finite()
            && self.first_mm.y_mm.is_finite())
        {
            return Err(TargetError::Sizes);
        }
        Ok(())
    }

    /// The dots' centres in reading order: top row (largest y) first, each
    /// row left to right, as an image shows them.
    pub fn points(&self) -> Vec<Point> {
        (0..self.rows)
            .rev()
            .flat_map(|j| {
                (0..self.cols).map(move |i| Point {
                    x_mm: self.first_mm.x_mm + f64::from(i) * self.spacing_mm[0],
                    y_mm: self.first_mm.y_mm + f64::from(j) * self.spacing_mm[1],
                })
            })
            .collect()
    }

    /// Each dot's floor point paired with where `image` shows its centre.
    pub fn find(&self, image: &RgbImage) -> Result<Vec<(Point, [f64; 2])>, CalibrationError> {
        let wanted = (self.cols * self.rows) as usize;
        if wanted < 4 {
            return Err(CalibrationError::TooFewPoints(wanted));
        }
        let grey = grey(image);
        let mask = binarise(&grey, otsu(&grey), true);
        let (found, _) = components(&mask, Connectivity::Eight);
        let (w, h) = image.dimensions();
        // Round, solid, and clear of the image's edge (walls touch it).
        let mut dots: Vec<_> = found
            .iter()
            .filter(|c| {
                let [x, y, bw, bh] = c.bbox;
                let inside = x > 0 && y > 0 && x + bw < w && y + bh < h;
                let fill = c.area as f64 / (f64::from(bw) * f64::from(bh));
                let square = f64::from(bw.min(bh)) / f64::from(bw.max(bh));
                inside
                    && c.area >= 5
                    && c.hole_area == 0
                    && (0.55..0.95).contains(&fill)
                    && square > 0.5
            })
            .collect();
        // The dots are one size: drop specks and blobs far from the median.
        let mut areas: Vec<u64> = dots.iter().map(|c| c.area).collect();
        areas.sort_unstable();
        if let Some(&median) = areas.get(areas.len() / 2) {
            let m = median as f64;
            dots.retain(|c| (0.4 * m..=2.5 * m).contains(&(c.area as f64)));
        }
        if dots.len() != wanted {
            return Err(CalibrationError::Target(format!(
                "found {} dots where the target has {} ({} × {}): is all of it in view and evenly lit?",
                dots.len(),
                wanted,
                self.cols,
                self.rows
            )));
        }
        // Reading order: by rows of `cols` dots from the top, each row left to right.
        let mut centres: Vec<[f64; 2]> = dots.iter().map(|c| weighted_centre(&grey, c)).collect();
        centres.sort_by(|a, b| a[1].total_cmp(&b[1]));
        for row in centres.chunks_mut(self.cols as usize) {
            row.sort_by(|a, b| a[0].total_cmp(&b[0]));
        }
        Ok(self.points().into_iter().zip(centres).collect())
    }

    /// The camera that took `image` of this target, at `fps`.
    pub fn calibrate(&self, image: &RgbImage, fps: f64) -> Result<Calibration, CalibrationError> {
        let pairs = self.find(image)?;
        CameraModel::calibrated(image.width(), image.height(), fps, &pairs)
    }
}

/// Where a dot's centre is, to a fraction of a pixel: its pixels (and
/// those a pixel around, which blur greys) weighted by how much darker
/// than the paper around it they are. The binary mask's centroid alone
/// moves by whole pixels as the dot's edge crosses them, which the lens's
/// fit would take for distortion. Pixel (c, r) covers [c, c+1) × [r, r+1):
/// its centre is c + ½.
fn weighted_centre(grey: &image::GrayImage, dot: &super::Component) -> [f64; 2] {
    let [x, y, w, h] = dot.bbox;
    let (iw, ih) = grey.dimensions();
    let (x0, y0) = (x.saturating_sub(2), y.saturating_sub(2));
    let (x1, y1) = ((x + w + 2).min(iw), (y + h + 2).min(ih));
    // The paper's level: the brightest of the ring just outside the box.
    let mut ring: Vec<u8> = Vec::new();
    for c in x0..x1 {
        ring.push(grey.get_pixel(c, y0).0[0]);
        ring.push(grey.get_pixel(c, y1 - 1).0[0]);
    }
    for r in y0..y1 {
        ring.push(grey.get_pixel(x0, r).0[0]);
        ring.push(grey.get_pixel(x1 - 1, r).0[0]);
    }
    ring.sort_unstable();
    let paper = f64::from(ring[ring.len() / 2]);
    let (mut sum, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for r in y0..y1 {
        for c in x0..x1 {
            let weight = (paper - f64::from(grey.get_pixel(c, r).0[0])).max(0.0);
            sum += weight;
            sx += weight * (f64::from(c) + 0.5);
            sy += weight * (f64::from(r) + 0.5);
        }
    }
    if sum > 0.0 {
        [sx / sum, sy / sum]
    } else {
        [dot.centroid.x + 0.5, dot.centroid.y + 0.5]
    }
}
