//! A webcam through Video4Linux2, by `linuxvideo` (plain Rust over the
//! kernel's ioctls: nothing to install to build it). The frame format is
//! chosen as the user asked or, by default, MJPEG (a USB 2 webcam sends VGA
//! at full rate only compressed) and else YUYV; the stream keeps two
//! buffers and `grab` takes the newest filled one. A device that goes away
//! (unplugged) fails `grab` until it can be opened again.

use std::path::{Path, PathBuf};
use std::time::Instant;

use linuxvideo::format::{FrameSizes, PixFormat, PixelFormat as Fourcc};
use linuxvideo::stream::ReadStream;
use linuxvideo::{BufType, Device, Fract};
use serde::Serialize;
use vl_core::{CameraModel, ImageSize, MAX_IMAGE_SIDE};
use vl_report::table::{Report, Table};

use super::pixels::{PixelFormat, decode};
use crate::drivers::{Camera, CameraError, Captured, believed};

/// What the user asked of the device: `v4l2:/dev/video0[,WxH][,Nfps][,mjpeg|yuyv]`.
#[derive(Debug, Clone, PartialEq)]
pub struct V4l2Spec {
    pub device: PathBuf,
    pub size: Option<(u32, u32)>,
    pub fps: Option<u32>,
    pub format: Option<PixelFormat>,
}

/// The smallest image side a webcam is asked for, px.
const MIN_SIDE: u32 = 16;

impl std::str::FromStr for V4l2Spec {
    type Err = CameraError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let mut parts = text.split(',');
        let device = parts.next().filter(|d| !d.is_empty()).ok_or_else(|| {
            CameraError::Address(
                "v4l2: needs a device, as v4l2:/dev/video0[,640x480][,15fps][,mjpeg|yuyv]".into(),
            )
        })?;
        let mut spec = V4l2Spec {
            device: device.into(),
            size: None,
            fps: None,
            format: None,
        };
        for part in parts {
            let lower = part.to_ascii_lowercase();
            if lower == "mjpeg" || lower == "mjpg" {
                spec.format = Some(PixelFormat::Mjpeg);
            } else if lower == "yuyv" {
                spec.format = Some(PixelFormat::Yuyv);
            } else if let Some(fps) = lower.strip_suffix("fps") {
                spec.fps = Some(
                    fps.parse()
                        .ok()
                        .filter(|f| (1..=240).contains(f))
                        .ok_or_else(|| {
                            CameraError::Address(format!(
                                "'{part}': a frame rate is 1fps to 240fps"
                            ))
                        })?,
                );
            } else if lower.contains('x') {
                let size = lower
                    .parse::<ImageSize>()
                    .ok()
                    .filter(|s| s.width >= MIN_SIDE && s.height >= MIN_SIDE)
                    .ok_or_else(|| {
                        CameraError::Address(format!(
                            "'{part}': a size is WIDTHxHEIGHT, {MIN_SIDE} to {MAX_IMAGE_SIDE} px a side"
                        ))
                    })?;
                spec.size = Some((size.width, size.height));
            } else {
                return Err(CameraError::Address(format!(
                    "'{part}' is no camera setting: give a size (640x480), a rate (15fps) or a format (mjpeg, yuyv)"
                )));
            }
        }
        Ok(spec)
    }
}

fn fourcc(format: PixelFormat) -> Fourcc {
    match format {
        PixelFormat::Mjpeg => Fourcc::MJPG,
        PixelFormat::Yuyv => Fourcc::YUYV,
    }
}

/// A webcam on V4L2.
pub struct V4l2Camera {
    spec: V4l2Spec,
    model: CameraModel,
    format: PixelFormat,
    stride: usize,
    stream: Option<ReadStream>,
}

/// A started stream, in the format it settled on: its width and the bytes
/// from one row to the next.
struct Started {
    stream: ReadStream,
    format: PixelFormat,
    width: u32,
    stride: usize,
}

/// Opens the device and starts its stream as `spec` asks.
fn start(spec: &V4l2Spec) -> Result<Started, CameraError> {
    let path = spec.device.display();
    let device = Device::open(&spec.device)
        .map_err(|e| CameraError::Setup(format!("cannot open {path}: {e}")))?;
    let offered: Vec<Fourcc> = device
        .formats(BufType::VIDEO_CAPTURE)
        .filter_map(|f| f.ok().map(|f| f.pixel_format()))
        .collect();
    let format = match spec.format {
        Some(format) if offered.contains(&fourcc(format)) => format,
        Some(format) => {
            return Err(CameraError::Setup(format!(
                "{path} does not offer {format}"
            )));
        }
        None if offered.contains(&Fourcc::MJPG) => PixelFormat::Mjpeg,
        None if offered.contains(&Fourcc::YUYV) => PixelFormat::Yuyv,
        None => {
            return Err(CameraError::Setup(format!(
                "{path} offers neither MJPEG nor YUYV (it offers {offered:?})"
            )));
        }
    };
    let (w, h) = spec.size.unwrap_or((640, 480));
    let capture = device
        .video_capture(PixFormat::new(w, h, fourcc(format)))
        .map_err(|e| CameraError::Setup(format!("{path} refuses {format} at {w}×{h}: {e}")))?;
    if let Some(fps) = spec.fps {
        capture
            .set_frame_interval(Fract::new(1, fps))
            .map_err(|e| {
                CameraError::Setup(format!("{path} refuses {fps} frames a second: {e}"))
            })?;
    }
    let (width, stride) = (capture.format().width(), capture.format().bytes_per_line());
    let stream = capture
        .into_stream()
        .map_err(|e| CameraError::Setup(format!("{path} will not stream: {e}")))?;
    Ok(Started {
        stream,
        format,
        width,
        stride: stride as usize,
    })
}

impl V4l2Camera {
    /// Opens the webcam `spec` names; it is seen through `model`, or
    /// (without one) as a camera looking straight down on a `floor_mm`
    /// floor.
    pub fn open(
        spec: V4l2Spec,
        model: Option<CameraModel>,
        floor_mm: (f64, f64),
    ) -> Result<V4l2Camera, CameraError> {
        let started = start(&spec)?;
        let fps = f64::from(spec.fps.unwrap_or(15));
        let model = believed(model, floor_mm, started.width, fps);
        Ok(V4l2Camera {
            stride: started.stride,
            spec,
            model,
            format: started.format,
            stream: Some(started.stream),
        })
    }
}

impl Camera for V4l2Camera {
    fn model(&self) -> CameraModel {
        self.model
    }

    fn grab(&mut self) -> Result<Captured, CameraError> {
        let path = self.spec.device.display().to_string();
        let stream = match &mut self.stream {
            Some(stream) => stream,
            None => {
                // Plugged in again? Start over, as asked.
                let started = start(&self.spec)?;
                (self.format, self.stride) = (started.format, started.stride);
                self.stream.insert(started.stream)
            }
        };
        let (w, h) = (self.model.width_px, self.model.height_px);
        let (format, stride) = (self.format, self.stride);
        let mut frame = None;
        // The newest filled buffer: older ones are passed over.
        let result = loop {
            let got = stream.dequeue(|buf| {
                if !buf.is_error() {
                    frame = Some((decode(format, &buf, w, h, stride), Instant::now()));
                }
                Ok(())
            });
            match got.and_then(|()| stream.will_block()) {
                Ok(true) => break Ok(()),
                Ok(false) => {}
                Err(e) => break Err(e),
            }
        };
        if let Err(e) = result {
            self.stream = None;
            return Err(CameraError::Silent(format!("{path}: {e}")));
        }
        match frame {
            Some((image, taken)) => Ok(Captured {
                image: image?,
                taken,
            }),
            None => Err(CameraError::Frame(format!("{path}: a damaged frame"))),
        }
    }
}

/// A video device and what it can capture.
#[derive(Debug, Clone, Serialize)]
pub struct DeviceInfo {
    pub path: PathBuf,
    pub card: String,
    pub driver: String,
    /// Each format it offers that `vl` reads, with its frame sizes and rates.
    pub modes: Vec<Mode>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Mode {
    pub format: PixelFormat,
    pub width: u32,
    pub height: u32,
    /// Frames a second, fastest first.
    pub fps: Vec<f64>,
}

/// The V4L2 capture devices on this machine.
pub fn list_devices() -> std::io::Result<Webcams> {
    let mut devices = Vec::new();
    for device in linuxvideo::list()?.flatten() {
        if let Some(info) = describe(&device) {
            devices.push(info);
        }
    }
    devices.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(Webcams(devices))
}

/// The webcams found.
#[derive(Debug, Serialize)]
#[serde(transparent)]
pub struct Webcams(pub Vec<DeviceInfo>);

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

fn describe(device: &Device) -> Option<DeviceInfo> {
    let caps = device.capabilities().ok()?;
    if !device
        .supported_buf_types()
        .contains(linuxvideo::BufTypes::VIDEO_CAPTURE)
    {
        return None;
    }
    let mut modes = Vec::new();
    for format in [PixelFormat::Mjpeg, PixelFormat::Yuyv] {
        let Ok(sizes) = device.frame_sizes(fourcc(format)) else {
            continue;
        };
        let sizes: Vec<(u32, u32)> = match sizes {
            FrameSizes::Discrete(list) => list.iter().map(|s| (s.width(), s.height())).collect(),
            FrameSizes::Stepwise(s) | FrameSizes::Continuous(s) => {
                vec![
                    (s.min_width(), s.min_height()),
                    (s.max_width(), s.max_height()),
                ]
            }
        };
        for (width, height) in sizes {
            let fps = device
                .frame_intervals(fourcc(format), width, height)
                .map(|ivals| rates(&ivals))
                .unwrap_or_default();
            modes.push(Mode {
                format,
                width,
                height,
                fps,
            });
        }
    }
    Some(DeviceInfo {
        path: device.path().unwrap_or_else(|_| Path::new("?").into()),
        card: caps.card().to_owned(),
        driver: caps.driver().to_owned(),
        modes,
    })
}

fn rates(ivals: &linuxvideo::format::FrameIntervals) -> Vec<f64> {
    let fps = |f: &Fract| f64::from(f.denominator()) / f64::from(f.numerator().max(1));
    let mut rates: Vec<f64> = match ivals {
        linuxvideo::format::FrameIntervals::Discrete(list) => {
            list.iter().map(|i| fps(i.fract())).collect()
        }
        _ => vec![fps(&ivals.min()), fps(&ivals.max())],
    };
    rates.sort_by(|a, b| b.total_cmp(a));
    rates.dedup();
    rates
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_settings_are_read_or_refused_with_a_reason() {
        let spec: V4l2Spec = "/dev/video2,1280x720,30fps,yuyv".parse().unwrap();
        assert_eq!(spec.device, PathBuf::from("/dev/video2"));
        assert_eq!(spec.size, Some((1280, 720)));
        assert_eq!(spec.fps, Some(30));
        assert_eq!(spec.format, Some(PixelFormat::Yuyv));
        let plain: V4l2Spec = "/dev/video0".parse().unwrap();
        assert_eq!((plain.size, plain.fps, plain.format), (None, None, None));
        for (text, says) in [
            ("", "needs a device"),
            ("/dev/video0,0fps", "1fps to 240fps"),
            ("/dev/video0,99999x1", "16 to 8192 px"),
            ("/dev/video0,h264", "'h264' is no camera setting"),
        ] {
            let e = text.parse::<V4l2Spec>().unwrap_err();
            assert!(e.to_string().contains(says), "{text}: {e}");
        }
    }
}
