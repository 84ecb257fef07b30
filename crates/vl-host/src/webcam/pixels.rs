//! A camera's buffer as a picture. MJPEG (a JPEG per frame, often without
//! its Huffman tables, which the decoder then takes as JPEG's standard
//! ones) and YUYV (4:2:2, two pixels in four bytes, BT.601's limited
//! range) are what webcams and network cameras deliver.

use image::{ImageFormat, RgbImage};
use vl_core::decode_image;

use crate::drivers::CameraError;

/// How a buffer's bytes hold the picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PixelFormat {
    Mjpeg,
    Yuyv,
}

impl std::fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PixelFormat::Mjpeg => "MJPEG",
            PixelFormat::Yuyv => "YUYV",
        })
    }
}

/// The picture in `bytes`, which must be `width`×`height` pixels (for
/// YUYV, rows `stride` bytes apart).
pub fn decode(
    format: PixelFormat,
    bytes: &[u8],
    width: u32,
    height: u32,
    stride: usize,
) -> Result<RgbImage, CameraError> {
    let image = match format {
        PixelFormat::Mjpeg => {
            // A frame larger than the camera's is dropped before it takes
            // the memory of its decoding.
            match declared_size(bytes) {
                Some(size) if size != (width, height) => {
                    return Err(CameraError::Frame(format!(
                        "a {}×{} px frame from a camera set to {width}×{height}: dropped undecoded",
                        size.0, size.1
                    )));
                }
                None => {
                    return Err(CameraError::Frame(
                        "an MJPEG frame with no frame header".to_owned(),
                    ));
                }
                Some(_) => {}
            }
            decode_image(&with_huffman_tables(bytes), Some(ImageFormat::Jpeg))
                .map_err(|e| CameraError::Frame(format!("an unreadable MJPEG frame: {e}")))?
                .to_rgb8()
        }
        PixelFormat::Yuyv => yuyv(bytes, width, height, stride)?,
    };
    if image.dimensions() != (width, height) {
        return Err(CameraError::Frame(format!(
            "a {}×{} px frame from a camera set to {width}×{height}",
            image.width(),
            image.height()
        )));
    }
    Ok(image)
}

/// JPEG's standard Huffman tables (ITU T.81 Annex K.3): for each of DC
/// luminance, DC chrominance, AC luminance, AC chrominance, its class and
/// id, the count of codes of each length 1–16, and the symbols.
const STANDARD_TABLES: [(u8, [u8; 16], &[u8]); 4] = [
    (
        0x00,
        [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
        &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
    ),
    (
        0x01,
        [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
        &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
    ),
    (
        0x10,
        [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d],
        &AC_LUMINANCE,
    ),
    (
        0x11,
        [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77],
        &AC_CHROMINANCE,
    ),
];

#[rustfmt::skip]
const AC_LUMINANCE: [u8; 162] = [
    0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61, 0x07,
    0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52, 0xd1, 0xf0,
    0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25, 0x26, 0x27, 0x28,
    0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49,
    0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69,
    0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89,
    0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7,
    0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5,
    0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2,
    0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8,
    0xf9, 0xfa,
];

#[rustfmt::skip]
const AC_CHROMINANCE: [u8; 162] = [
    0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61, 0x71,
    0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33, 0x52, 0xf0,
    0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26,
    0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48,
    0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68,
    0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x82, 0x83, 0x84, 0x85, 0x86, 0x87,
    0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5,
    0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3,
    0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda,
    0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8,
    0xf9, 0xfa,
];

/// The frame with JPEG's standard Huffman tables put before its scan when
/// it has none of its own, as USB webcams' MJPEG leaves them out (UVC
/// says the standard ones apply).
fn with_huffman_tables(jpeg: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    for (marker, i) in segments(jpeg) {
        match marker {
            0xC4 => return jpeg.into(),
            0xDA => {
                let mut segment = Vec::with_capacity(420);
                for (class_id, counts, symbols) in STANDARD_TABLES {
                    segment.push(class_id);
                    segment.extend_from_slice(&counts);
                    segment.extend_from_slice(symbols);
                }
                let mut out = Vec::with_capacity(jpeg.len() + segment.len() + 4);
                out.extend_from_slice(&jpeg[..i]);
                out.extend_from_slice(&[0xFF, 0xC4]);
                out.extend_from_slice(&((segment.len() + 2) as u16).to_be_bytes());
                out.extend_from_slice(&segment);
                out.extend_from_slice(&jpeg[i..]);
                return out.into();
            }
            _ => {}
        }
    }
    jpeg.into()
}

/// The JPEG's segments from SOI to the start of scan: each marker, and
/// where its segment begins.
fn segments(jpeg: &[u8]) -> impl Iterator<Item = (u8, usize)> + '_ {
    let mut i = 2;
    std::iter::from_fn(move || {
        if i + 4 > jpeg.len() || jpeg[i] != 0xFF {
            return None;
        }
        let at = i;
        let marker = jpeg[i + 1];
        // Nothing is read past the start of scan.
        i = if marker == 0xDA {
            usize::MAX - 4
        } else {
            i + 2 + usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]]))
        };
        Some((marker, at))
    })
}

/// The widest or tallest camera a lab takes, px: a first frame declaring
/// more is refused before it is decoded.
pub const MAX_CAMERA_SIDE: u32 = 4096;

/// The size a JPEG declares in its frame header (width, height), read
/// without decoding anything.
pub fn declared_size(jpeg: &[u8]) -> Option<(u32, u32)> {
    // SOF0–SOF15, but for DHT (C4), JPG (C8) and DAC (CC).
    let (_, at) = segments(jpeg)
        .find(|&(m, _)| (0xC0..=0xCF).contains(&m) && !matches!(m, 0xC4 | 0xC8 | 0xCC))?;
    let header = jpeg.get(at + 5..at + 9)?;
    let height = u16::from_be_bytes([header[0], header[1]]);
    let width = u16::from_be_bytes([header[2], header[3]]);
    Some((u32::from(width), u32::from(height)))
}

fn yuyv(bytes: &[u8], width: u32, height: u32, stride: usize) -> Result<RgbImage, CameraError> {
    let row = width as usize * 2;
    let stride = stride.max(row);
    let needed = stride * (height as usize).saturating_sub(1) + row;
    if !width.is_multiple_of(2) || bytes.len() < needed {
        return Err(CameraError::Frame(format!(
            "a YUYV frame of {} bytes cannot be {width}×{height} px",
            bytes.len()
        )));
    }
    let mut out = RgbImage::new(width, height);
    for (y, pixels) in out.chunks_exact_mut(width as usize * 3).enumerate() {
        let line = &bytes[y * stride..y * stride + row];
        for (quad, rgb) in line.chunks_exact(4).zip(pixels.chunks_exact_mut(6)) {
            let (u, v) = (i32::from(quad[1]) - 128, i32::from(quad[3]) - 128);
            for (k, luma) in [quad[0], quad[2]].into_iter().enumerate() {
                let c = 298 * (i32::from(luma) - 16) + 128;
                let px = &mut rgb[3 * k..3 * k + 3];
                px[0] = ((c + 409 * v) >> 8).clamp(0, 255) as u8;
                px[1] = ((c - 100 * u - 208 * v) >> 8).clamp(0, 255) as u8;
                px[2] = ((c + 516 * u) >> 8).clamp(0, 255) as u8;
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yuyv_greys_and_primaries_come_out_as_rgb() {
        // Black, white, and a mid grey pair; then pure red by its Y, U, V.
        let bytes = [16, 128, 235, 128, 126, 128, 126, 128, 81, 90, 81, 240];
        let image = decode(PixelFormat::Yuyv, &bytes, 2, 3, 4).unwrap();
        assert_eq!(image.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(image.get_pixel(1, 0).0, [255, 255, 255]);
        assert_eq!(image.get_pixel(0, 1).0, [128, 128, 128]);
        let red = image.get_pixel(0, 2).0;
        assert!(red[0] > 250 && red[1] < 5 && red[2] < 5, "{red:?}");
        let e = decode(PixelFormat::Yuyv, &bytes[..10], 2, 3, 4).unwrap_err();
        assert!(e.to_string().contains("cannot be 2×3 px"), "{e}");
    }
}

#[cfg(test)]
mod mjpeg_tests {
    use super::*;

    /// A JPEG with its Huffman tables (DHT segments) cut out, as many
    /// webcams send MJPEG.
    fn without_huffman_tables(jpeg: &[u8]) -> Vec<u8> {
        let mut out = jpeg[..2].to_vec();
        let mut i = 2;
        while i + 4 <= jpeg.len() {
            let marker = jpeg[i + 1];
            if marker == 0xDA {
                out.extend_from_slice(&jpeg[i..]);
                break;
            }
            let len = usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]]));
            if marker != 0xC4 {
                out.extend_from_slice(&jpeg[i..i + 2 + len]);
            }
            i += 2 + len;
        }
        out
    }

    #[test]
    fn mjpeg_without_huffman_tables_decodes() {
        let image = RgbImage::from_fn(64, 48, |x, y| {
            image::Rgb([(x * 4) as u8, (y * 5) as u8, 128])
        });
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90)
            .encode_image(&image)
            .unwrap();
        let bare = without_huffman_tables(&jpeg);
        assert!(bare.len() < jpeg.len());
        // The encoder used the standard tables: put back, they decode the
        // very same pixels.
        let decoded = decode(PixelFormat::Mjpeg, &bare, 64, 48, 0).unwrap();
        let whole = decode(PixelFormat::Mjpeg, &jpeg, 64, 48, 0).unwrap();
        assert_eq!(decoded, whole);
        let Err(e) = decode(PixelFormat::Mjpeg, b"\xFF\xD8 not a frame", 64, 48, 0) else {
            panic!("noise decoded as a frame");
        };
        assert!(e.to_string().contains("no frame header"), "{e}");
    }

    #[test]
    fn a_frame_larger_than_the_camera_is_dropped_undecoded() {
        let image = RgbImage::new(64, 48);
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90)
            .encode_image(&image)
            .unwrap();
        assert_eq!(declared_size(&jpeg), Some((64, 48)));
        // The same frame declaring 8192×8192: refused by its header alone
        // (decoded, it would take 200 MB).
        let (_, sof) = segments(&jpeg).find(|&(m, _)| m == 0xC0).unwrap();
        jpeg[sof + 5..sof + 9].copy_from_slice(&[0x20, 0x00, 0x20, 0x00]);
        let Err(e) = decode(PixelFormat::Mjpeg, &jpeg, 64, 48, 0) else {
            panic!("an 8192×8192 frame taken from a 64×48 camera");
        };
        assert!(e.to_string().contains("8192×8192 px frame"), "{e}");
        assert!(e.to_string().contains("dropped undecoded"), "{e}");
    }
}
