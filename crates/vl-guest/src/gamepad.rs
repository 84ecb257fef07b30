//! A real gamepad or joystick as the operator's stick: its left stick
//! drives, a button is the emergency stop, another (optionally) the
//! dead-man switch that must be held for the stick to count; the force the
//! Host feeds back is rendered as rumble of matching strength and, on
//! joysticks that take it, as a constant force in its direction.
//!
//! Devices are read through Linux's evdev, which needs no system library
//! to build against (gilrs, the usual crate, needs libudev's headers, and
//! `vl` builds with nothing but Rust). The mappings from the device to the
//! stick and from the force to the effects are pure functions, tested
//! without any device.

use std::path::PathBuf;

use vl_core::Joystick;

/// Readings within this of centre count as the stick at rest: sticks
/// rarely return exactly to it.
pub(crate) const DEAD_ZONE: f64 = 0.08;

/// An absolute axis's range, as the device reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct AxisRange {
    pub minimum: i32,
    pub maximum: i32,
}

impl AxisRange {
    /// A raw value as −1..1 from the minimum to the maximum, with the dead
    /// zone at the centre taken out.
    pub(crate) fn normalise(&self, raw: i32) -> f64 {
        let span = f64::from(self.maximum) - f64::from(self.minimum);
        if span <= 0.0 {
            return 0.0;
        }
        let v = ((f64::from(raw) - f64::from(self.minimum)) / span * 2.0 - 1.0).clamp(-1.0, 1.0);
        if v.abs() < DEAD_ZONE {
            0.0
        } else {
            v.signum() * (v.abs() - DEAD_ZONE) / (1.0 - DEAD_ZONE)
        }
    }
}

/// What the operator does with the gamepad, in this frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadInput {
    /// x to the right, y forward: evdev's y grows toward the operator.
    pub stick: Joystick,
    /// The emergency stop button is down.
    pub emergency_stop: bool,
    /// The dead-man button is held (always true when none is required).
    pub dead_man: bool,
}

impl PadInput {
    /// The stick as the robot should take it: at rest unless the dead-man
    /// button is held.
    pub fn drive(&self) -> Joystick {
        if self.dead_man {
            self.stick
        } else {
            Joystick::default()
        }
    }
}

/// The stick from its two axes' normalised readings (y as evdev reports
/// it, positive toward the operator), kept within the unit circle.
pub(crate) fn stick(x: f64, y_toward_operator: f64) -> Joystick {
    let (x, y) = (x, -y_toward_operator);
    let length = x.hypot(y);
    if length > 1.0 {
        Joystick {
            x: x / length,
            y: y / length,
        }
    } else {
        Joystick { x, y }
    }
}

/// A stick the operator holds: what the window reads each frame and where
/// it renders the force.
pub trait Pad {
    fn name(&self) -> &str;
    /// Whether it can render force (rumble or a constant force).
    fn has_force_feedback(&self) -> bool {
        false
    }
    /// What the operator does now.
    fn poll(&mut self) -> PadInput;
    /// Renders the obstacles' push, in joystick axes.
    fn render(&mut self, force: [f64; 2]);
}

/// What a force becomes on the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Effect {
    /// Rumble motors' magnitudes (strong, weak), 0–65535.
    pub rumble: (u16, u16),
    /// A constant force: its direction in Linux's convention (0 pushes the
    /// stick down, toward the operator; 0x4000 left; 0x8000 up; 0xC000
    /// right) and its level, 0–32767.
    pub constant: Option<(u16, i16)>,
}

/// Forces weaker than this are not rendered: the pad stays still in the open.
pub(crate) const FELT: f64 = 0.02;

/// The effect for `force` in joystick axes (x right, y forward, each −1..1):
/// rumble as strong as the force, and a constant force pushing the stick
/// the way the force points.
pub fn effect(force: [f64; 2]) -> Effect {
    let [x, y] = force.map(|f| {
        if f.is_finite() {
            f.clamp(-1.0, 1.0)
        } else {
            0.0
        }
    });
    let strength = x.hypot(y).min(1.0);
    if strength < FELT {
        return Effect::default();
    }
    // The angle from "down" turning toward "left": down is (0, −1), left (−1, 0).
    let angle = (-x).atan2(-y).rem_euclid(std::f64::consts::TAU);
    let direction = (angle / std::f64::consts::TAU * 65536.0).round() as u32 % 65536;
    Effect {
        rumble: (
            (strength * 65535.0).round() as u16,
            (strength * 0.5 * 65535.0).round() as u16,
        ),
        constant: Some((direction as u16, (strength * 32767.0).round() as i16)),
    }
}

#[cfg(target_os = "linux")]
pub use device::Gamepad;

/// Why the gamepad asked for cannot be driven with.
#[derive(Debug, thiserror::Error)]
pub enum GamepadError {
    #[error("cannot open {path}: {source}")]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{0} has no stick (absolute X and Y axes) and buttons")]
    NotAGamepad(PathBuf),
    #[error("gamepads are read through Linux's evdev only")]
    Unsupported,
}

/// Which gamepad the operator drives with, as `--gamepad` names it.
#[derive(Clone, Debug)]
pub enum PadChoice {
    /// The first gamepad or joystick found, if any.
    Auto,
    None,
    /// The device at this path (`/dev/input/eventN`).
    Device(PathBuf),
}

impl std::str::FromStr for PadChoice {
    type Err = std::convert::Infallible;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Ok(match text {
            "auto" => PadChoice::Auto,
            "none" => PadChoice::None,
            path => PadChoice::Device(path.into()),
        })
    }
}

impl PadChoice {
    /// The gamepad chosen, open; none when none is asked for or found.
    pub fn open(&self, needs_dead_man: bool) -> Result<Option<Box<dyn Pad>>, GamepadError> {
        #[cfg(target_os = "linux")]
        {
            let pad = match self {
                PadChoice::None => None,
                PadChoice::Auto => Gamepad::find(needs_dead_man),
                PadChoice::Device(path) => Some(Gamepad::open(path, needs_dead_man)?),
            };
            Ok(pad.map(|p| Box::new(p) as Box<dyn Pad>))
        }
        #[cfg(not(target_os = "linux"))]
        match self {
            PadChoice::Device(_) => Err(GamepadError::Unsupported),
            _ => {
                let _ = needs_dead_man;
                Ok(None)
            }
        }
    }
}

#[cfg(target_os = "linux")]
mod device {
    use std::path::Path;

    use super::{AxisRange, Effect, GamepadError, Pad, PadInput, effect, stick};
    use evdev::{
        AbsoluteAxisCode, Device, EventSummary, FFEffect, FFEffectCode, FFEffectData, FFEffectKind,
        FFEnvelope, FFReplay, FFTrigger, KeyCode,
    };

    /// Buttons that stop the robot: B on a pad, the thumb button on a joystick.
    const STOP_BUTTONS: [KeyCode; 2] = [KeyCode::BTN_EAST, KeyCode::BTN_THUMB];
    /// The dead-man switch: the left shoulder on a pad, the trigger on a joystick.
    const DEAD_MAN_BUTTONS: [KeyCode; 2] = [KeyCode::BTN_TL, KeyCode::BTN_TRIGGER];
    /// How long an uploaded effect plays unless renewed, ms.
    const EFFECT_MS: u16 = 200;

    /// An open gamepad or joystick.
    pub struct Gamepad {
        device: Device,
        name: String,
        axes: [AxisRange; 2],
        raw: [i32; 2],
        stop_down: bool,
        dead_man_down: bool,
        needs_dead_man: bool,
        rumble: Option<FFEffect>,
        constant: Option<FFEffect>,
        shown: Effect,
    }

    fn is_gamepad(device: &Device) -> bool {
        let axes = device.supported_absolute_axes();
        let keys = device.supported_keys();
        axes.is_some_and(|a| {
            a.contains(AbsoluteAxisCode::ABS_X) && a.contains(AbsoluteAxisCode::ABS_Y)
        }) && keys.is_some_and(|k| STOP_BUTTONS.iter().any(|b| k.contains(*b)))
    }

    impl Gamepad {
        /// The first gamepad or joystick among the input devices, if any.
        pub fn find(needs_dead_man: bool) -> Option<Gamepad> {
            evdev::enumerate()
                .find(|(_, device)| is_gamepad(device))
                .and_then(|(path, _)| Gamepad::open(&path, needs_dead_man).ok())
        }

        /// The gamepad at `path` (`/dev/input/eventN`).
        pub fn open(path: &Path, needs_dead_man: bool) -> Result<Gamepad, GamepadError> {
            let open = |source| GamepadError::Open {
                path: path.to_owned(),
                source,
            };
            let device = Device::open(path).map_err(open)?;
            if !is_gamepad(&device) {
                return Err(GamepadError::NotAGamepad(path.to_owned()));
            }
            device.set_nonblocking(true).map_err(open)?;
            let state = device.get_abs_state().map_err(open)?;
            let range = |axis: AbsoluteAxisCode| {
                let info = state[axis.0 as usize];
                AxisRange {
                    minimum: info.minimum,
                    maximum: info.maximum,
                }
            };
            let axes = [
                range(AbsoluteAxisCode::ABS_X),
                range(AbsoluteAxisCode::ABS_Y),
            ];
            let centre = |r: &AxisRange| (r.minimum + r.maximum) / 2;
            let name = device.name().unwrap_or("gamepad").to_owned();
            let mut pad = Gamepad {
                raw: [centre(&axes[0]), centre(&axes[1])],
                device,
                name,
                axes,
                stop_down: false,
                dead_man_down: false,
                needs_dead_man,
                rumble: None,
                constant: None,
                shown: Effect::default(),
            };
            pad.prepare_effects();
            Ok(pad)
        }

        /// Uploads the effects the device supports, at rest.
        fn prepare_effects(&mut self) {
            let supported = self.device.supported_ff().map(|s| {
                (
                    s.contains(FFEffectCode::FF_RUMBLE),
                    s.contains(FFEffectCode::FF_CONSTANT),
                )
            });
            let (rumble, constant) = supported.unwrap_or((false, false));
            if rumble {
                self.rumble = self.device.upload_ff_effect(rumble_data(0, 0)).ok();
            }
            if constant {
                self.constant = self.device.upload_ff_effect(constant_data(0, 0)).ok();
            }
        }
    }

    impl Pad for Gamepad {
        fn name(&self) -> &str {
            &self.name
        }

        fn has_force_feedback(&self) -> bool {
            self.rumble.is_some() || self.constant.is_some()
        }

        /// Takes in what happened since the last call.
        fn poll(&mut self) -> PadInput {
            if let Ok(events) = self.device.fetch_events() {
                for event in events {
                    match event.destructure() {
                        EventSummary::AbsoluteAxis(_, AbsoluteAxisCode::ABS_X, v) => {
                            self.raw[0] = v
                        }
                        EventSummary::AbsoluteAxis(_, AbsoluteAxisCode::ABS_Y, v) => {
                            self.raw[1] = v
                        }
                        EventSummary::Key(_, key, v) if STOP_BUTTONS.contains(&key) => {
                            self.stop_down = v != 0;
                        }
                        EventSummary::Key(_, key, v) if DEAD_MAN_BUTTONS.contains(&key) => {
                            self.dead_man_down = v != 0;
                        }
                        _ => {}
                    }
                }
            }
            PadInput {
                stick: stick(
                    self.axes[0].normalise(self.raw[0]),
                    self.axes[1].normalise(self.raw[1]),
                ),
                emergency_stop: self.stop_down,
                dead_man: !self.needs_dead_man || self.dead_man_down,
            }
        }

        /// Renders `force` (joystick axes) as rumble and a constant force.
        fn render(&mut self, force: [f64; 2]) {
            let wanted = effect(force);
            if wanted == self.shown {
                return;
            }
            self.shown = wanted;
            if let Some(rumble) = &mut self.rumble {
                let (strong, weak) = wanted.rumble;
                let _ = rumble.update(rumble_data(strong, weak));
                let _ = if strong > 0 {
                    rumble.play(1)
                } else {
                    rumble.stop()
                };
            }
            if let Some(constant) = &mut self.constant {
                let (direction, level) = wanted.constant.unwrap_or((0, 0));
                let _ = constant.update(constant_data(direction, level));
                let _ = if level > 0 {
                    constant.play(1)
                } else {
                    constant.stop()
                };
            }
        }
    }

    fn replay() -> FFReplay {
        FFReplay {
            length: EFFECT_MS,
            delay: 0,
        }
    }

    fn rumble_data(strong: u16, weak: u16) -> FFEffectData {
        FFEffectData {
            direction: 0,
            trigger: FFTrigger::default(),
            replay: replay(),
            kind: FFEffectKind::Rumble {
                strong_magnitude: strong,
                weak_magnitude: weak,
            },
        }
    }

    fn constant_data(direction: u16, level: i16) -> FFEffectData {
        FFEffectData {
            direction,
            trigger: FFTrigger::default(),
            replay: replay(),
            kind: FFEffectKind::Constant {
                level,
                envelope: FFEnvelope {
                    attack_length: 0,
                    attack_level: 0,
                    fade_length: 0,
                    fade_level: 0,
                },
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn axes_read_as_a_stick_with_its_dead_zone() {
        let r = AxisRange {
            minimum: 0,
            maximum: 255,
        };
        assert_eq!(r.normalise(128), 0.0, "centre");
        assert_eq!(r.normalise(0), -1.0);
        assert_eq!(r.normalise(255), 1.0);
        assert_eq!(r.normalise(135), 0.0, "inside the dead zone");
        // Pushed away from the operator (evdev's y down), the robot goes forward.
        let forward = stick(0.0, -1.0);
        assert_eq!(forward, Joystick { x: 0.0, y: 1.0 });
        let corner = stick(1.0, -1.0);
        assert!((corner.x.hypot(corner.y) - 1.0).abs() < 1e-12);
        let pad = PadInput {
            stick: forward,
            emergency_stop: false,
            dead_man: false,
        };
        assert_eq!(pad.drive(), Joystick::default(), "no dead man, no motion");
    }

    #[test]
    fn forces_point_the_way_linux_counts_directions() {
        let dir = |f: [f64; 2]| effect(f).constant.unwrap().0;
        assert_eq!(
            dir([0.0, -1.0]),
            0x0000,
            "pushed back: down, toward the operator"
        );
        assert_eq!(dir([-1.0, 0.0]), 0x4000, "left");
        assert_eq!(dir([0.0, 1.0]), 0x8000, "up");
        assert_eq!(dir([1.0, 0.0]), 0xC000, "right");
        assert_eq!(effect([0.0, 0.01]), Effect::default(), "too weak to feel");
        assert_eq!(effect([f64::NAN, 1.0]).constant.unwrap().0, 0x8000);
    }

    proptest! {
        /// Stronger forces rumble harder, always within the motors' range,
        /// and the constant force points where the force does.
        #[test]
        fn the_effect_follows_the_force(x in -1.5f64..1.5, y in -1.5f64..1.5, k in 0.0f64..1.0) {
            let (strong, weaker) = (effect([x, y]), effect([x * k, y * k]));
            prop_assert!(weaker.rumble.0 <= strong.rumble.0);
            if let Some((direction, level)) = strong.constant {
                prop_assert!(level > 0);
                let angle = f64::from(direction) / 65536.0 * std::f64::consts::TAU;
                let (px, py) = (-angle.sin(), -angle.cos());
                let (fx, fy) = (x.clamp(-1.0, 1.0), y.clamp(-1.0, 1.0));
                let cos = (px * fx + py * fy) / fx.hypot(fy);
                prop_assert!(cos > 0.9999, "direction {:#x} for {:?}", direction, (x, y));
            }
        }
    }
}
