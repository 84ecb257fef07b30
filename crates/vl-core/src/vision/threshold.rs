//! From colour to foreground: OpenCV's grey conversion, Otsu's threshold
//! and binarisation.

use std::str::FromStr;

use image::{GrayImage, RgbImage};

/// A binary image: `true` is foreground.
#[derive(Debug, Clone, PartialEq)]
pub struct Mask {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<bool>,
}

/// The grey level that splits foreground from background.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Threshold {
    /// Otsu's: chosen per frame from its histogram.
    Otsu,
    /// A fixed grey level, 0–255.
    Level(u8),
}

/// A threshold that is neither `otsu` nor a grey level.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a threshold is 'otsu' or a grey level 0–255, not '{0}'")]
pub struct ThresholdError(String);

impl FromStr for Threshold {
    type Err = ThresholdError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "otsu" => Ok(Threshold::Otsu),
            level => level
                .parse()
                .map(Threshold::Level)
                .map_err(|_| ThresholdError(text.to_owned())),
        }
    }
}

/// Grey level of each pixel: (9798 R + 19235 G + 3735 B + 2¹⁴) >> 15, the
/// 0.299/0.587/0.114 weights in OpenCV's 15-bit fixed point.
pub fn grey(image: &RgbImage) -> GrayImage {
    let (w, h) = image.dimensions();
    let mut out = GrayImage::new(w, h);
    for (o, p) in out.as_mut().iter_mut().zip(image.as_raw().chunks_exact(3)) {
        let [r, g, b] = [u32::from(p[0]), u32::from(p[1]), u32::from(p[2])];
        *o = ((9798 * r + 19235 * g + 3735 * b + (1 << 14)) >> 15) as u8;
    }
    out
}

/// Otsu's threshold: the grey level t that best splits the histogram into
/// [0, t] and (t, 255] (largest between-class variance, first on ties).
pub fn otsu(image: &GrayImage) -> u8 {
    let mut histogram = [0u64; 256];
    for &v in image.as_raw() {
        histogram[usize::from(v)] += 1;
    }
    let total = image.as_raw().len().max(1) as f64;
    let mean: f64 = (0..256)
        .map(|i| i as f64 * histogram[i] as f64)
        .sum::<f64>()
        / total;
    let (mut q1, mut mu1, mut best, mut best_sigma) = (0.0f64, 0.0f64, 0u8, 0.0f64);
    for (i, &count) in histogram.iter().enumerate() {
        let p = count as f64 / total;
        mu1 *= q1;
        q1 += p;
        let q2 = 1.0 - q1;
        if q1.min(q2) < f64::from(f32::EPSILON) || q1.max(q2) > 1.0 - f64::from(f32::EPSILON) {
            continue;
        }
        mu1 = (mu1 + i as f64 * p) / q1;
        let mu2 = (mean - q1 * mu1) / q2;
        let sigma = q1 * q2 * (mu1 - mu2) * (mu1 - mu2);
        if sigma > best_sigma {
            best_sigma = sigma;
            best = i as u8;
        }
    }
    best
}

/// Foreground where grey > `threshold` (or ≤ it when `invert`: dark objects
/// on a light floor).
pub fn binarise(image: &GrayImage, threshold: u8, invert: bool) -> Mask {
    Mask {
        width: image.width(),
        height: image.height(),
        pixels: image
            .as_raw()
            .iter()
            .map(|&v| (v > threshold) != invert)
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn otsu_splits_two_levels_between_them() {
        let image = GrayImage::from_fn(10, 10, |c, _| image::Luma([if c < 4 { 40 } else { 200 }]));
        let t = otsu(&image);
        assert!((40..200).contains(&t), "{t}");
    }

    #[test]
    fn thresholds_are_otsu_or_a_grey_level() {
        assert_eq!("otsu".parse(), Ok(Threshold::Otsu));
        assert_eq!("128".parse(), Ok(Threshold::Level(128)));
        let e = "256".parse::<Threshold>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "a threshold is 'otsu' or a grey level 0–255, not '256'"
        );
    }
}
