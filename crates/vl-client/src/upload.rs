//! The user's own controller sent to the Host: its file read (refused
//! unread when too large), then sent in parts, each well within a
//! message's size, in order.

use std::path::Path;

use base64::Engine as _;
use vl_core::{GuestMessage, MAX_MODULE_BYTES};

/// Why a controller's file was not read.
#[derive(Debug, thiserror::Error)]
pub enum ControllerFileError {
    #[error("{path}: {size} bytes; a controller may have at most {MAX_MODULE_BYTES} (2 MiB)")]
    TooLarge { path: String, size: u64 },
    #[error("{path}: {why}")]
    Unreadable { path: String, why: std::io::Error },
}

/// A controller's file, refused before it is read when it is larger than
/// a controller may be: a huge file costs nothing.
pub fn read_controller(path: &Path) -> Result<Vec<u8>, ControllerFileError> {
    let unreadable = |why| ControllerFileError::Unreadable {
        path: path.display().to_string(),
        why,
    };
    let size = std::fs::metadata(path).map_err(unreadable)?.len();
    if size > MAX_MODULE_BYTES as u64 {
        return Err(ControllerFileError::TooLarge {
            path: path.display().to_string(),
            size,
        });
    }
    std::fs::read(path).map_err(unreadable)
}

/// The file's bytes a part carries: 512 KiB, some 700 KB of base64.
const PART_BYTES: usize = 512 << 10;

/// The `controller` messages that send `file`, first to last.
pub fn controller_parts(file: &[u8]) -> Vec<GuestMessage> {
    let total = file.len() as u64;
    file.chunks(PART_BYTES)
        .enumerate()
        .map(|(i, part)| GuestMessage::Controller {
            offset: (i * PART_BYTES) as u64,
            total,
            data: base64::engine::general_purpose::STANDARD.encode(part),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{MAX_MODULE_BYTES, MAX_TEXT_BYTES, Wire};

    #[test]
    fn the_largest_module_goes_in_parts_each_within_a_message() {
        let parts = controller_parts(&vec![7; MAX_MODULE_BYTES]);
        assert_eq!(parts.len(), 4);
        for part in &parts {
            assert!(part.encode().len() < MAX_TEXT_BYTES);
        }
        let GuestMessage::Controller { offset, total, .. } = &parts[3] else {
            panic!("{:?}", parts[3]);
        };
        assert_eq!(
            (*offset, *total),
            (3 * (512 << 10), MAX_MODULE_BYTES as u64)
        );
    }
}
