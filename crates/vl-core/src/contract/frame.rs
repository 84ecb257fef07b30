//! Camera frames on the wire: a binary WebSocket message is a fixed
//! little-endian header followed by the encoded image (JPEG or PNG).
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | magic `VLF1` |
//! | 4 | format: 1 = JPEG, 2 = PNG |
//! | 5..8 | reserved, zero |
//! | 8..10 | width, px (u16) |
//! | 10..12 | height, px (u16) |
//! | 12..20 | frame sequence number (u64) |
//! | 20..28 | event number the frame was taken at (u64) |
//! | 28..36 | capture time, µs since the session started (u64) |
//! | 36.. | the image |

use thiserror::Error;

/// Bytes before the image payload.
pub(crate) const HEADER_LEN: usize = 36;
const MAGIC: &[u8; 4] = b"VLF1";

/// The largest frame either side accepts.
pub const MAX_FRAME_BYTES: usize = 8 << 20;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    Jpeg,
    Png,
}

/// What a receiver needs to place a frame: which one, of which event, when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameHeader {
    pub format: ImageFormat,
    pub width: u16,
    pub height: u16,
    pub seq: u64,
    pub event: u64,
    pub capture_us: u64,
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    #[error("frame of {0} bytes is shorter than its {HEADER_LEN}-byte header")]
    Truncated(usize),
    #[error("frame does not start with the VLF1 magic")]
    BadMagic,
    #[error("frame has unknown image format {0}")]
    UnknownFormat(u8),
    #[error("frame carries no image")]
    Empty,
    #[error("frame of {len} bytes is over the {max}-byte limit")]
    TooLarge { len: usize, max: usize },
}

impl FrameHeader {
    /// The header followed by `image`, ready to send as one binary message.
    pub fn encode(&self, image: &[u8]) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER_LEN + image.len());
        out.extend_from_slice(MAGIC);
        out.push(match self.format {
            ImageFormat::Jpeg => 1,
            ImageFormat::Png => 2,
        });
        out.extend_from_slice(&[0; 3]);
        out.extend_from_slice(&self.width.to_le_bytes());
        out.extend_from_slice(&self.height.to_le_bytes());
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.event.to_le_bytes());
        out.extend_from_slice(&self.capture_us.to_le_bytes());
        out.extend_from_slice(image);
        out
    }

    /// Splits a binary message into its header and image bytes.
    pub fn decode(bytes: &[u8]) -> Result<(FrameHeader, &[u8]), FrameError> {
        if bytes.len() > MAX_FRAME_BYTES {
            return Err(FrameError::TooLarge {
                len: bytes.len(),
                max: MAX_FRAME_BYTES,
            });
        }
        if bytes.len() < HEADER_LEN {
            return Err(FrameError::Truncated(bytes.len()));
        }
        if &bytes[..4] != MAGIC {
            return Err(FrameError::BadMagic);
        }
        let format = match bytes[4] {
            1 => ImageFormat::Jpeg,
            2 => ImageFormat::Png,
            other => return Err(FrameError::UnknownFormat(other)),
        };
        let u16_at = |i: usize| u16::from_le_bytes([bytes[i], bytes[i + 1]]);
        let u64_at = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[i..i + 8]);
            u64::from_le_bytes(b)
        };
        let header = FrameHeader {
            format,
            width: u16_at(8),
            height: u16_at(10),
            seq: u64_at(12),
            event: u64_at(20),
            capture_us: u64_at(28),
        };
        let image = &bytes[HEADER_LEN..];
        if image.is_empty() {
            return Err(FrameError::Empty);
        }
        Ok((header, image))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn frames_round_trip(
            png in any::<bool>(), width in any::<u16>(), height in any::<u16>(),
            seq in any::<u64>(), event in any::<u64>(), capture_us in any::<u64>(),
            image in proptest::collection::vec(any::<u8>(), 1..256),
        ) {
            let h = FrameHeader {
                format: if png { ImageFormat::Png } else { ImageFormat::Jpeg },
                width, height, seq, event, capture_us,
            };
            let wire = h.encode(&image);
            let (back, payload) = FrameHeader::decode(&wire).unwrap();
            prop_assert_eq!(back, h);
            prop_assert_eq!(payload, &image[..]);
        }

        #[test]
        fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..128)) {
            let _ = FrameHeader::decode(&bytes);
        }
    }

    #[test]
    fn bad_frames_are_named() {
        assert_eq!(FrameHeader::decode(b"VLF1"), Err(FrameError::Truncated(4)));
        let mut wire = FrameHeader {
            format: ImageFormat::Png,
            width: 1,
            height: 1,
            seq: 0,
            event: 0,
            capture_us: 0,
        }
        .encode(b"x");
        wire[4] = 9;
        assert_eq!(
            FrameHeader::decode(&wire),
            Err(FrameError::UnknownFormat(9))
        );
        wire[0] = b'X';
        assert_eq!(FrameHeader::decode(&wire), Err(FrameError::BadMagic));
    }
}
