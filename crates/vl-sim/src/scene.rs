//! What people do in a lab during a run, scheduled on the virtual clock:
//! put an obstacle on the floor, or hold a hand over the robot so the
//! camera loses it. They exercise what the camera and the Host must cope
//! with: a scene that changes, a robot out of sight.

use std::str::FromStr;

use vl_core::{Shape, SyntaxError};

/// Something a person does.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneEvent {
    /// An obstacle is put on the floor.
    Place(Shape),
    /// A hand covers the robot from the camera for this many seconds.
    Cover(f64),
}

/// A scene event at a time on the lab's clock.
#[derive(Debug, Clone, PartialEq)]
pub struct Scheduled {
    pub at_s: f64,
    pub event: SceneEvent,
}

/// The longest a hand may cover the robot, s.
const MAX_COVER_S: f64 = 3600.0;

impl FromStr for Scheduled {
    type Err = SyntaxError;

    /// `T:place:SHAPE` (e.g. `3:place:rect:400,100,40,40`) or `T:cover:SECONDS`.
    fn from_str(text: &str) -> Result<Scheduled, SyntaxError> {
        let expected = "expected T:place:SHAPE or T:cover:SECONDS";
        let form = || SyntaxError::Form {
            expected,
            got: text.to_owned(),
        };
        let (at, rest) = text.split_once(':').ok_or_else(form)?;
        let at_s: f64 = at
            .trim()
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite() && *t >= 0.0)
            .ok_or_else(|| SyntaxError::Range {
                got: at.to_owned(),
                what: "a time in seconds from 0 on".into(),
            })?;
        let (kind, what) = rest.split_once(':').ok_or_else(form)?;
        let event = match kind {
            "place" => SceneEvent::Place(what.parse()?),
            "cover" => SceneEvent::Cover(
                what.trim()
                    .parse()
                    .ok()
                    .filter(|s: &f64| s.is_finite() && *s > 0.0 && *s <= MAX_COVER_S)
                    .ok_or_else(|| SyntaxError::Range {
                        got: what.to_owned(),
                        what: format!("a cover time from 0 to {MAX_COVER_S} s"),
                    })?,
            ),
            other => {
                return Err(SyntaxError::Unknown {
                    kind: "scene event",
                    got: other.to_owned(),
                    expected,
                });
            }
        };
        Ok(Scheduled { at_s, event })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_parse_and_bad_ones_say_why() {
        let placed: Scheduled = "3:place:rect:400,100,40,40".parse().unwrap();
        assert_eq!(placed.at_s, 3.0);
        assert!(matches!(
            placed.event,
            SceneEvent::Place(Shape::Rect { .. })
        ));
        let covered: Scheduled = "1.5:cover:2".parse().unwrap();
        assert_eq!(covered.event, SceneEvent::Cover(2.0));
        for bad in [
            "",
            "3",
            "x:cover:2",
            "-1:cover:2",
            "1:cover:inf",
            "1:wave:2",
            "1:place:cube:1",
        ] {
            assert!(bad.parse::<Scheduled>().is_err(), "{bad}");
        }
    }
}
