//! How positions, shapes and scene events are written on a command line:
//! comma-separated numbers, and what is wrong with text that says none.

use std::net::SocketAddr;
use std::str::FromStr;
use std::time::Duration;

use crate::{MAX_IMAGE_SIDE, ShapeError};

/// Text that does not say what it should, in words a user can act on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SyntaxError {
    #[error("'{0}' is not a number")]
    NotANumber(String),
    #[error("'{0}' is not a finite number")]
    NotFinite(String),
    /// Text of another form than `expected` says.
    #[error("{expected}, not '{got}'")]
    Form { expected: &'static str, got: String },
    #[error("unknown {kind} '{got}': {expected}")]
    Unknown {
        kind: &'static str,
        got: String,
        expected: &'static str,
    },
    /// A number outside what it may be.
    #[error("'{got}' is not {what}")]
    Range { got: String, what: String },
    #[error(transparent)]
    Shape(#[from] ShapeError),
}

/// Comma-separated finite numbers.
pub(crate) fn parse_numbers(text: &str) -> Result<Vec<f64>, SyntaxError> {
    text.split(',')
        .map(|n| {
            let v: f64 = n
                .trim()
                .parse()
                .map_err(|_| SyntaxError::NotANumber(n.to_owned()))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(SyntaxError::NotFinite(n.to_owned()))
            }
        })
        .collect()
}

/// An address to listen on, suggesting the form when it is not one
/// (`localhost` is a name, not an address and port).
pub fn listen_address(text: &str) -> Result<SocketAddr, SyntaxError> {
    text.parse().map_err(|_| {
        let port = text.rsplit_once(':').map_or("7400", |(_, p)| p);
        SyntaxError::Range {
            got: text.to_owned(),
            what: format!(
                "an address and port: give 127.0.0.1:{port} for this machine only, \
                 or 0.0.0.0:{port} for every network it is on"
            ),
        }
    })
}

/// A length of time as people write it: seconds (`90`, `90s`, `1.5`),
/// minutes (`10m`) or hours (`1h`); more than nothing and at most a day.
pub fn duration(text: &str) -> Result<Duration, SyntaxError> {
    let refused = || SyntaxError::Range {
        got: text.to_owned(),
        what: "a time from 0 to a day, as 90, 90s, 10m or 1h".into(),
    };
    let t = text.trim();
    let (number, unit) = match t.char_indices().last() {
        Some((i, 'h')) => (&t[..i], 3600.0),
        Some((i, 'm')) => (&t[..i], 60.0),
        Some((i, 's')) => (&t[..i], 1.0),
        _ => (t, 1.0),
    };
    let seconds = number.trim().parse::<f64>().map_err(|_| refused())? * unit;
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 86_400.0) {
        return Err(refused());
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// A [`duration`], or `0` for none at all.
pub fn duration_or_none(text: &str) -> Result<Duration, SyntaxError> {
    match text.trim().parse::<f64>() {
        Ok(0.0) => Ok(Duration::ZERO),
        _ => duration(text),
    }
}

/// An image's size in pixels, written WxH (640x480 or 640×480), each side
/// from 1 to [`MAX_IMAGE_SIDE`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSize {
    pub width: u32,
    pub height: u32,
}

impl FromStr for ImageSize {
    type Err = SyntaxError;

    fn from_str(text: &str) -> Result<ImageSize, SyntaxError> {
        let (w, h) = text
            .split_once(['x', 'X', '×'])
            .ok_or_else(|| SyntaxError::Range {
                got: text.to_owned(),
                what: "WxH, e.g. 640x480".into(),
            })?;
        let side = |v: &str| {
            v.trim()
                .parse::<u32>()
                .ok()
                .filter(|v| (1..=MAX_IMAGE_SIDE).contains(v))
                .ok_or_else(|| SyntaxError::Range {
                    got: v.to_owned(),
                    what: format!("a size in pixels from 1 to {MAX_IMAGE_SIDE}"),
                })
        };
        Ok(ImageSize {
            width: side(w)?,
            height: side(h)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_duration_is_seconds_minutes_or_hours_up_to_a_day() {
        assert_eq!(duration("90"), Ok(Duration::from_secs(90)));
        assert_eq!(duration("1.5s"), Ok(Duration::from_millis(1500)));
        assert_eq!(duration("10m"), Ok(Duration::from_secs(600)));
        assert_eq!(duration(" 1h "), Ok(Duration::from_secs(3600)));
        for bad in ["0", "-5m", "25h", "NaNs", "m", "ten minutes", "1e400"] {
            let e = duration(bad).unwrap_err().to_string();
            assert!(e.contains("a time from 0 to a day"), "{bad}: {e}");
        }
    }

    #[test]
    fn an_image_size_is_two_sides_within_the_limit() {
        let size = |t: &str| t.parse::<ImageSize>();
        assert_eq!(
            size("640x480"),
            Ok(ImageSize {
                width: 640,
                height: 480
            })
        );
        assert_eq!(
            size(" 8 × 6"),
            Ok(ImageSize {
                width: 8,
                height: 6
            })
        );
        let refused = |t: &str| size(t).unwrap_err().to_string();
        assert_eq!(refused("640"), "'640' is not WxH, e.g. 640x480");
        assert!(refused("0x10").contains("from 1 to 8192"));
        assert!(refused("10x9000").starts_with("'9000' is not a size"));
        assert!(refused("axb").starts_with("'a' is not a size"));
    }
}
