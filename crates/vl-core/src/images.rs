//! Images from outside — map files, camera frames, frames to inspect —
//! decoded within limits, so a small file that declares a huge picture is
//! refused instead of taking gigabytes and seconds.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageFormat, ImageReader, Limits};

/// The largest side of an image `vl` decodes, px.
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// The most memory one decoding may take, bytes.
const MAX_IMAGE_BYTES: u64 = 256 << 20;

fn limits() -> Limits {
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    limits
}

/// An image that could not be read or decoded.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error(transparent)]
    Read(#[from] std::io::Error),
    #[error(transparent)]
    Decode(#[from] image::ImageError),
}

/// The image in the file at `path`, its format guessed from its content.
pub fn load_image(path: &Path) -> Result<DynamicImage, ImageError> {
    let mut reader = ImageReader::open(path).and_then(|r| r.with_guessed_format())?;
    reader.limits(limits());
    Ok(reader.decode()?)
}

/// The image encoded in `bytes`, in `format` or, without one, as guessed.
pub fn decode_image(bytes: &[u8], format: Option<ImageFormat>) -> Result<DynamicImage, ImageError> {
    let mut reader = match format {
        Some(format) => ImageReader::with_format(Cursor::new(bytes), format),
        None => ImageReader::new(Cursor::new(bytes)).with_guessed_format()?,
    };
    reader.limits(limits());
    Ok(reader.decode()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_file_declaring_a_huge_picture_is_refused() {
        // A PNG header for 20000 × 20000 pixels, and nothing behind it.
        let image = image::GrayImage::new(1, 1);
        let mut png = Vec::new();
        image
            .write_to(&mut Cursor::new(&mut png), ImageFormat::Png)
            .unwrap();
        png[16..20].copy_from_slice(&20_000u32.to_be_bytes());
        png[20..24].copy_from_slice(&20_000u32.to_be_bytes());
        // The IHDR chunk's CRC covers its type and data, bytes 12..29.
        let crc = crc32fast::hash(&png[12..29]);
        png[29..33].copy_from_slice(&crc.to_be_bytes());
        let started = std::time::Instant::now();
        let e = decode_image(&png, Some(ImageFormat::Png)).unwrap_err();
        assert!(e.to_string().contains("limit"), "{e}");
        assert!(started.elapsed().as_secs_f64() < 1.0);
        let fine = {
            let mut bytes = Vec::new();
            image
                .write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
                .unwrap();
            bytes
        };
        assert_eq!(decode_image(&fine, None).unwrap().width(), 1);
    }
}
