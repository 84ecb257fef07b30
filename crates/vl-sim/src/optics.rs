//! How a real camera spoils the ideal overhead view: its lens (offset,
//! tilt, radial distortion, blur), its lamp (a lighting gradient), its
//! sensor (noise), its timing (delay, exposure, dropped frames) and what
//! gets in the way (a hidden marker).

use image::RgbImage;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use vl_core::{CameraModel, Distortion};

use crate::noise::gaussian;

/// How the simulated camera departs from an ideal one. All zero (the
/// default) renders the ideal image; with any of them the frame is still
/// a pure function of the world and the seed.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Optics {
    /// Shift of the image, px (columns right, rows down), as when the lens
    /// sits off the sensor's axis; lab staff calibrate it away.
    pub lens_offset_px: [f64; 2],
    /// Gaussian blur, standard deviation in px.
    pub blur_px: f64,
    /// Per-pixel Gaussian noise, standard deviation in grey levels.
    pub noise: f64,
    /// How much darker the bottom-right corner is than the top-left one
    /// (0 to 1), as under a single lamp.
    pub lighting_gradient: f64,
    /// Seed of the noise; each frame also mixes in the virtual time.
    pub seed: u64,
    /// How far the camera leans from looking straight down, rad (towards
    /// the floor's +y side, which then looks narrower).
    pub tilt_rad: f64,
    /// The lens's radial distortion.
    pub distortion: Distortion,
    /// From a frame's exposure to its arrival at the Host, s: a webcam's
    /// capture, compression and transfer.
    pub delay_s: f64,
    /// How long the shutter is open, s: a robot moving meanwhile is smeared.
    pub exposure_s: f64,
    /// The share of frames lost on the way (a USB or network hiccup).
    pub drop_rate: f64,
    /// The share of frames in which something (a cable, a hand) hides
    /// part of the robot's marker.
    pub occlusion_rate: f64,
}

/// Camera options no camera has, named.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OpticsError {
    #[error("the camera may lean at most 45° from looking straight down, not {0:.1}°")]
    Tilt(f64),
    #[error("the lens offset must be finite")]
    LensOffset,
    #[error("the camera {what} must be zero or more, not {value}")]
    Negative { what: &'static str, value: f64 },
    #[error(transparent)]
    Lens(#[from] vl_core::LensError),
    #[error("the camera's delay is 0 to 2 s, not {0} s")]
    Delay(f64),
    #[error("the camera's exposure is 0 to 0.2 s, not {0} s")]
    Exposure(f64),
    #[error("the {what} is 0 to 0.5, not {value}")]
    Share { what: &'static str, value: f64 },
    #[error("the lighting gradient must be between 0 and 1, not {0}")]
    Lighting(f64),
}

/// A simulated camera's optics to start from: an ideal camera looking
/// straight down (`none`); lens offset, blur, noise and a lighting
/// gradient, as an inexpensive webcam over a lab bench (`noisy`); or that
/// with a wide lens's barrel distortion, 80 ms from exposure to arrival,
/// 20 ms exposures, 5 % of frames lost and 5 % with the robot's marker
/// partly hidden (`realistic`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OpticsPreset {
    None,
    Noisy,
    Realistic,
}

impl vl_core::Named for OpticsPreset {
    const KIND: &'static str = "optics";
    const ALL: &'static [OpticsPreset] = &[
        OpticsPreset::None,
        OpticsPreset::Noisy,
        OpticsPreset::Realistic,
    ];

    fn id(self) -> &'static str {
        match self {
            OpticsPreset::None => "none",
            OpticsPreset::Noisy => "noisy",
            OpticsPreset::Realistic => "realistic",
        }
    }
}

vl_core::named_by_id!(OpticsPreset);

impl OpticsPreset {
    /// The preset's optics, its noise drawn from `seed`.
    pub fn optics(self, seed: u64) -> Optics {
        match self {
            OpticsPreset::None => Optics {
                seed,
                ..Optics::default()
            },
            OpticsPreset::Noisy => Optics::noisy(seed),
            OpticsPreset::Realistic => Optics::realistic(seed),
        }
    }
}

impl Optics {
    /// Lens offset, blur, sensor noise and a lighting gradient together, as
    /// an inexpensive webcam over a lab bench shows the floor.
    pub fn noisy(seed: u64) -> Optics {
        Optics {
            lens_offset_px: [5.0, -3.0],
            blur_px: 0.8,
            noise: 4.0,
            lighting_gradient: 0.3,
            seed,
            ..Optics::default()
        }
    }

    /// An overhead webcam as a lab has one: the noisy camera's sensor, and
    /// a wide lens's barrel distortion, 80 ms from exposure to arrival,
    /// 20 ms exposures, one frame in 20 lost and one in 20 with the marker
    /// partly hidden.
    pub fn realistic(seed: u64) -> Optics {
        Optics {
            distortion: Distortion {
                k1: -0.18,
                k2: 0.08,
            },
            delay_s: 0.08,
            exposure_s: 0.02,
            drop_rate: 0.05,
            occlusion_rate: 0.05,
            ..Optics::noisy(seed)
        }
    }

    /// The camera that really takes the picture when the lab believes in
    /// `nominal`, over a `width_mm` × `height_mm` floor: tilted if the
    /// optics say so (the lens offset shifts its images on top).
    pub fn view(&self, nominal: &CameraModel, width_mm: f64, height_mm: f64) -> CameraModel {
        if self.tilt_rad == 0.0 {
            return nominal.with_distortion(self.distortion);
        }
        CameraModel::tilted(
            width_mm,
            height_mm,
            nominal.width_px,
            nominal.height_px,
            self.tilt_rad,
            nominal.fps,
        )
        // `check` keeps the tilt within what looks at the floor.
        .unwrap_or(*nominal)
        .with_distortion(self.distortion)
    }

    /// Whether the options make sense, naming the one that does not.
    pub fn check(&self) -> Result<(), OpticsError> {
        if !(self.tilt_rad.is_finite()
            && self.tilt_rad.abs() <= std::f64::consts::FRAC_PI_4 + 1e-12)
        {
            return Err(OpticsError::Tilt(self.tilt_rad.to_degrees()));
        }
        let [dx, dy] = self.lens_offset_px;
        if !(dx.is_finite() && dy.is_finite()) {
            return Err(OpticsError::LensOffset);
        }
        for (what, value) in [("blur", self.blur_px), ("noise", self.noise)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(OpticsError::Negative { what, value });
            }
        }
        // A 4:3 image's corners: where a lens bends most.
        self.distortion.check(640, 480)?;
        if !(self.delay_s.is_finite() && (0.0..=2.0).contains(&self.delay_s)) {
            return Err(OpticsError::Delay(self.delay_s));
        }
        if !(self.exposure_s.is_finite() && (0.0..=0.2).contains(&self.exposure_s)) {
            return Err(OpticsError::Exposure(self.exposure_s));
        }
        for (what, value) in [
            ("share of frames dropped", self.drop_rate),
            (
                "share of frames with the marker hidden",
                self.occlusion_rate,
            ),
        ] {
            if !(0.0..=0.5).contains(&value) {
                return Err(OpticsError::Share { what, value });
            }
        }
        if !(0.0..=1.0).contains(&self.lighting_gradient) {
            return Err(OpticsError::Lighting(self.lighting_gradient));
        }
        Ok(())
    }
}

/// Blur, lighting and noise, in that order (as lens, lamp and sensor).
pub(crate) fn finish(image: &mut RgbImage, optics: &Optics, time_s: f64) {
    if optics.blur_px > 0.0 {
        blur(image, optics.blur_px);
    }
    let size = image.dimensions();
    light(image, optics, (0, 0), size);
    if optics.noise > 0.0 {
        add_noise(image, optics, optics.seed ^ (time_s * 1e3).round() as u64);
    }
}

/// A separable Gaussian blur of standard deviation `sigma` px, edges
/// clamped, on the image's raw bytes (a pixel's channels side by side).
pub(crate) fn blur(image: &mut RgbImage, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as usize;
    let weights: Vec<f32> = (0..=2 * radius)
        .map(|k| {
            let i = k as f64 - radius as f64;
            (-(i * i) / (2.0 * sigma * sigma)).exp() as f32
        })
        .collect();
    let total: f32 = weights.iter().sum();
    let weights: Vec<f32> = weights.iter().map(|w| w / total).collect();
    let (w, h) = (image.width() as usize, image.height() as usize);
    // Along rows, then along columns: `step` bytes between neighbours,
    // `len` of them in a line, `lines` lines `stride` bytes apart.
    for (step, len, stride, lines) in [(3, w, 3 * w, h), (3 * w, h, 3, w)] {
        let source = image.as_raw().clone();
        let out: &mut [u8] = image;
        for line in 0..lines {
            let base = line * stride;
            for i in 0..len {
                for ch in 0..3 {
                    let mut acc = 0f32;
                    for (k, weight) in weights.iter().enumerate() {
                        let j = (i + k).saturating_sub(radius).min(len - 1);
                        acc += weight * f32::from(source[base + j * step + ch]);
                    }
                    // Rounded half up: `as` truncates what is never negative.
                    out[base + i * step + ch] = (acc.clamp(0.0, 255.0) + 0.5) as u8;
                }
            }
        }
    }
}

/// Darkens towards the bottom-right corner of a `size` image, of which
/// `image` is the part from `origin`: as under a single lamp.
pub(crate) fn light(image: &mut RgbImage, optics: &Optics, origin: (u32, u32), size: (u32, u32)) {
    if optics.lighting_gradient <= 0.0 {
        return;
    }
    let (w, h) = (size.0 as f32, size.1 as f32);
    let gradient = optics.lighting_gradient as f32;
    for (c, r, px) in image.enumerate_pixels_mut() {
        let along = ((origin.0 + c) as f32 / w + (origin.1 + r) as f32 / h) / 2.0;
        let gain = 1.0 - gradient * along;
        for ch in px.0.iter_mut() {
            // Rounded half up: `as` truncates what is never negative.
            *ch = (f32::from(*ch) * gain + 0.5) as u8;
        }
    }
}

/// Adds a sensor's noise: on every channel of every pixel, 15 times a
/// second, too many Gaussian draws to make one by one, so each pixel takes
/// one random word and three draws from a table of them.
pub(crate) fn add_noise(image: &mut RgbImage, optics: &Optics, seed: u64) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let table = gaussian_table();
    let noise = optics.noise as f32;
    for px in image.chunks_exact_mut(3) {
        let word = rng.next_u64();
        for (k, ch) in px.iter_mut().enumerate() {
            let draw = table[((word >> (16 * k)) & 0xFFFF) as usize];
            let v = (f32::from(*ch) + noise * draw).clamp(0.0, 255.0);
            *ch = (v + 0.5) as u8;
        }
    }
}

/// 65,536 standard Gaussian draws, the same on every run.
fn gaussian_table() -> &'static [f32] {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut rng = Pcg64Mcg::seed_from_u64(0x5EED);
        (0..1 << 16).map(|_| gaussian(&mut rng) as f32).collect()
    })
}
