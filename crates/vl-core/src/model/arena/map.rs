//! Arenas drawn as a top-view image: its dark pixels become obstacles.

use image::GrayImage;
use serde::Deserialize;

use crate::Shape;

/// A top-view image of the arena: its dark pixels are obstacles.
#[derive(Debug, Deserialize)]
pub(crate) struct MapImage {
    pub(crate) image: String,
    pub(crate) mm_per_px: f64,
    #[serde(default = "MapImage::mid_grey")]
    pub(crate) threshold: u8,
}

impl MapImage {
    fn mid_grey() -> u8 {
        128
    }
}

/// The pixels of `image` darker than `threshold`, as few rectangles (mm, in
/// the ROS map frame): runs of dark pixels along each row, merged with the
/// identical run of the row below.
pub(crate) fn dark_boxes(image: &GrayImage, threshold: u8, mm_per_px: f64) -> Vec<Shape> {
    let (w, h) = image.dimensions();
    let mut done = Vec::new();
    // Runs still growing downwards: (first column, end column) → first row.
    let mut open: std::collections::BTreeMap<(u32, u32), u32> = Default::default();
    let close = |(c0, c1): (u32, u32), r0: u32, r1: u32| Shape::Rect {
        x_mm: f64::from(c0) * mm_per_px,
        y_mm: f64::from(h - r1) * mm_per_px,
        width_mm: f64::from(c1 - c0) * mm_per_px,
        height_mm: f64::from(r1 - r0) * mm_per_px,
    };
    for r in 0..=h {
        let mut runs = Vec::new();
        let mut c = 0;
        while r < h && c < w {
            if image.get_pixel(c, r).0[0] < threshold {
                let start = c;
                while c < w && image.get_pixel(c, r).0[0] < threshold {
                    c += 1;
                }
                runs.push((start, c));
            }
            c += 1;
        }
        let mut next = std::collections::BTreeMap::new();
        for run in runs {
            next.insert(run, open.remove(&run).unwrap_or(r));
        }
        for (run, r0) in std::mem::replace(&mut open, next) {
            done.push(close(run, r0, r));
        }
    }
    done
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Point;
    use proptest::prelude::*;

    fn p(x_mm: f64, y_mm: f64) -> Point {
        Point { x_mm, y_mm }
    }

    proptest! {
        /// A map's rectangles cover exactly its dark pixels.
        #[test]
        fn dark_boxes_cover_the_dark_pixels(w in 1u32..12, h in 1u32..12, seed in any::<u64>()) {
            let mut state = seed | 1;
            let image = GrayImage::from_fn(w, h, |_, _| {
                state ^= state << 13; state ^= state >> 7; state ^= state << 17;
                image::Luma([if state % 3 == 0 { 20 } else { 200 }])
            });
            let boxes = dark_boxes(&image, 128, 2.0);
            for (c, r, px) in image.enumerate_pixels() {
                let centre = p((f64::from(c) + 0.5) * 2.0, (f64::from(h - r) - 0.5) * 2.0);
                let covered = boxes.iter().filter(|b| b.distance(centre) == 0.0).count();
                prop_assert_eq!(covered, usize::from(px.0[0] < 128), "pixel ({}, {})", c, r);
            }
        }
    }
}
