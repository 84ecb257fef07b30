//! The libraries' typed options as the flags several commands share: the
//! simulated camera's optics, which frames the Host sends, what a forecast
//! must show. Each turns into the library's own type here, and only here.

#[cfg(feature = "host")]
use std::time::Duration;

#[cfg(feature = "host")]
use vl_host::{ForecastSettings, FramePolicy, MOST_FORECAST_SEEDS};
use vl_sim::{Optics, OpticsPreset};

/// The simulated camera's optics, as `vl host`, `vl sim`, `vl camera`
/// and `vl experiment` take them.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct OpticsArgs {
    /// Optics to start from: none (an ideal camera looking straight
    /// down), noisy (a cheap webcam: offset, blur, noise, uneven light) or
    /// realistic (noisy, a wide lens, 80 ms late, motion blur, 5 % lost).
    #[arg(long, value_parser = crate::named::<OpticsPreset>(), default_value = "none")]
    optics: OpticsPreset,
    /// Image shift in px, as DX,DY (lens off the sensor's axis).
    #[arg(long, allow_hyphen_values = true)]
    lens_offset: Option<vl_core::Point>,
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
    lens: Option<vl_core::Point>,
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
    pub(crate) fn optics(&self, seed: u64) -> Result<Optics, vl_sim::OpticsError> {
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
        optics.check()?;
        Ok(optics)
    }
}

#[cfg(feature = "host")]
/// Which camera frames the Host sends (thesis appendix G), as `vl host`
/// and `vl experiment` take it from flags.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct FrameArgs {
    /// Which frames: every-frame (every frame the camera takes: live
    /// video) or on-change (only when the scene changes beyond the robot,
    /// when a Guest asks, and at least every --frame-interval; Guests draw
    /// the robot from its pose).
    #[arg(long, value_parser = crate::named::<FrameChoice>(), default_value = "every-frame")]
    frames: FrameChoice,
    /// With --frames on-change: the longest time between two frames (5, 5s, 1m).
    #[arg(long, default_value = "5", value_parser = crate::duration)]
    frame_interval: Duration,
}

#[cfg(feature = "host")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FrameChoice {
    EveryFrame,
    OnChange,
}

#[cfg(feature = "host")]
impl vl_core::Named for FrameChoice {
    const KIND: &'static str = "frames";
    const ALL: &'static [FrameChoice] = &[FrameChoice::EveryFrame, FrameChoice::OnChange];

    fn id(self) -> &'static str {
        match self {
            FrameChoice::EveryFrame => "every-frame",
            FrameChoice::OnChange => "on-change",
        }
    }
}

#[cfg(feature = "host")]
impl FrameArgs {
    pub(crate) fn policy(&self) -> FramePolicy {
        match self.frames {
            FrameChoice::EveryFrame => FramePolicy::EveryFrame,
            FrameChoice::OnChange => FramePolicy::OnChange {
                max_interval: self.frame_interval,
            },
        }
    }
}

#[cfg(feature = "host")]
/// What a lab asks of a navigation definition's forecast before a run
/// may start, besides reaching the goal without contact (`vl host` flags,
/// or keys of its lab file).
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub(crate) struct ForecastArgs {
    /// The least room, mm, the forecast robot may come to anything.
    #[arg(long = "min-clearance", value_name = "MM", default_value_t = 0.0, value_parser = clearance, allow_hyphen_values = true)]
    min_clearance_mm: f64,
    /// The longest a run may be forecast to take (90s, 10m).
    #[arg(long, value_parser = crate::duration)]
    max_run: Option<Duration>,
    /// How many seeds of sensor and wheel noise each forecast tries.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=i64::from(MOST_FORECAST_SEEDS)))]
    forecast_seeds: u32,
}

#[cfg(feature = "host")]
/// A clearance in mm: a finite number from 0 to a metre.
fn clearance(text: &str) -> Result<f64, String> {
    text.parse::<f64>()
        .ok()
        .filter(|mm| (0.0..=1000.0).contains(mm))
        .ok_or_else(|| format!("{text:?} is not a clearance from 0 to 1000 mm"))
}

#[cfg(feature = "host")]
impl ForecastArgs {
    pub(crate) fn settings(&self) -> ForecastSettings {
        ForecastSettings {
            min_clearance_mm: self.min_clearance_mm,
            max_run: self.max_run,
            forecast_seeds: self.forecast_seeds,
        }
    }
}

/// A Zenoh endpoint as the flags take it: read by the gateway's crate in a
/// vl that has one, else kept as given, to say which feature it needs.
#[cfg(feature = "zenoh")]
pub(crate) type ZenohEndpoint = vl_cells::Endpoint;
#[cfg(all(feature = "host", not(feature = "zenoh")))]
pub(crate) type ZenohEndpoint = String;

#[cfg(feature = "host")]
/// Where `vl` meets a Zenoh network: its own router listening, or an
/// existing network joined.
#[derive(clap::Args, Clone)]
pub(crate) struct ZenohArgs {
    /// Where the embedded Zenoh router listens (tcp/HOST:PORT, or
    /// quic/HOST:PORT): by default port 7447 on --listen's address.
    #[arg(long, conflicts_with = "zenoh")]
    zenoh_listen: Vec<ZenohEndpoint>,
    /// Join an existing Zenoh network here instead (a site's zenohd, a
    /// gateway's router), with no router of its own.
    #[arg(long)]
    zenoh: Vec<ZenohEndpoint>,
    /// The certificate to join a quic/ network with: the file `vl gateway
    /// issue` wrote for this machine.
    #[arg(long, value_name = "FILE")]
    zenoh_credentials: Option<std::path::PathBuf>,
}

#[cfg(feature = "zenoh")]
/// Zenoh's usual port, where ROS 2's rmw_zenoh looks for a router.
const ZENOH_PORT: u16 = 7447;

#[cfg(feature = "zenoh")]
impl ZenohArgs {
    /// The network, a router of its own listening on `listen`'s address
    /// unless told otherwise (`quic/` where `secured`: its caller then says
    /// who may join it).
    pub(crate) fn options(
        &self,
        listen: std::net::SocketAddr,
        secured: bool,
    ) -> anyhow::Result<vl_cells::ZenohOptions> {
        if self.zenoh.is_empty() {
            let listen = match self.zenoh_listen.as_slice() {
                [] => vec![vl_cells::Endpoint::new(secured, listen.ip(), ZENOH_PORT)],
                given => given.to_vec(),
            };
            Ok(vl_cells::ZenohOptions {
                connect: Vec::new(),
                listen,
                trust: vl_cells::ZenohTrust::Open,
            })
        } else {
            self.joining(self.zenoh.clone())
        }
    }

    /// Joining `connect`, with the credentials given, if any.
    pub(crate) fn joining(
        &self,
        connect: Vec<vl_cells::Endpoint>,
    ) -> anyhow::Result<vl_cells::ZenohOptions> {
        Ok(vl_cells::ZenohOptions {
            connect,
            listen: Vec::new(),
            trust: self.credentials()?.map_or(vl_cells::ZenohTrust::Open, |c| {
                vl_cells::ZenohTrust::Member(std::sync::Arc::new(c))
            }),
        })
    }

    /// The credentials `--zenoh-credentials` names, read.
    pub(crate) fn credentials(&self) -> anyhow::Result<Option<vl_cells::ZenohCredentials>> {
        self.zenoh_credentials
            .as_deref()
            .map(|file| {
                vl_cells::ZenohCredentials::load(file).map_err(|e| {
                    anyhow::Error::new(crate::BadInput(format!("--zenoh-credentials: {e}")))
                })
            })
            .transpose()
    }
}
