//! The Khepera I/II serial protocol (BIOS 5.x), once for both of its ends:
//! the Host's driver writes commands and reads replies, the emulator reads
//! commands and writes replies.
//!
//! A command is one upper-case letter and optional `,int` arguments; the
//! reply is the same letter in lower case and `,values`. Unknown commands
//! and bad arguments are answered `z,…`. Line endings (CR, LF, CRLF) are
//! the caller's: these types speak single lines without them.

use thiserror::Error;

/// A command to the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KheperaCommand {
    /// `A,Kp,Ki,Kd`: the speed controller's gains.
    SpeedGains { kp: i64, ki: i64, kd: i64 },
    /// `B`: BIOS and protocol versions.
    Version,
    /// `C,l,r`: drive each wheel to an encoder position, pulses.
    MoveTo { left: i64, right: i64 },
    /// `D,l,r`: wheel speeds, pulses per 10 ms.
    SetSpeed { left: i64, right: i64 },
    /// `E`: the wheels' speeds.
    ReadSpeed,
    /// `F,Kp,Ki,Kd`: the position controller's gains.
    PositionGains { kp: i64, ki: i64, kd: i64 },
    /// `G,l,r`: set the encoder counters.
    SetCounters { left: i64, right: i64 },
    /// `H`: the encoder counters.
    ReadCounters,
    /// `J,top_l,acc_l,top_r,acc_r`: the speed profile of position moves.
    SpeedProfile { top: [i64; 2], accel: [i64; 2] },
    /// `K`: each motor's controller status.
    ReadStatus,
    /// `L,n,action`: LED 0 or 1 off, on or toggled.
    Led { led: u8, action: LedAction },
    /// `N`: the proximity sensors, 0–1023, higher is nearer.
    ReadProximity,
    /// `O`: ambient light at the sensors, lower is brighter.
    ReadAmbient,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LedAction {
    Off,
    On,
    Toggle,
}

/// A controller's state, as `K` reports it per motor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MotorStatus {
    pub on_target: bool,
    pub mode: MotorMode,
    /// Speed or position error, pulses.
    pub error: i64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotorMode {
    Speed,
    Position,
}

/// The robot's answer to one command.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum KheperaReply {
    /// The command was carried out: its letter in lower case, no values
    /// (`a`, `c`, `d`, `f`, `g`, `j`, `l`).
    Done(char),
    Version {
        bios: String,
        protocol: String,
    },
    Speed([i64; 2]),
    Counters([i64; 2]),
    Status([MotorStatus; 2]),
    Proximity(Vec<u16>),
    Ambient(Vec<u16>),
    /// `z,reason`: the command was not understood.
    Refused(String),
}

/// Why a command line is not one the robot carries out.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CommandError {
    #[error("Command not found")]
    Unknown,
    #[error("Bad arguments")]
    BadArguments,
}

/// A reply line that is not one the protocol has.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("'{0}' is not a Khepera reply")]
pub struct MalformedReply(pub String);

/// Letters of the commands answered by [`KheperaReply::Done`].
const DONE_LETTERS: &str = "acdfgjl";

fn join(letter: char, values: &[String]) -> String {
    std::iter::once(letter.to_string())
        .chain(values.iter().cloned())
        .collect::<Vec<_>>()
        .join(",")
}

fn numbers<T: ToString>(values: &[T]) -> Vec<String> {
    values.iter().map(ToString::to_string).collect()
}

impl KheperaCommand {
    /// The command's upper-case letter.
    pub fn letter(&self) -> char {
        match self {
            KheperaCommand::SpeedGains { .. } => 'A',
            KheperaCommand::Version => 'B',
            KheperaCommand::MoveTo { .. } => 'C',
            KheperaCommand::SetSpeed { .. } => 'D',
            KheperaCommand::ReadSpeed => 'E',
            KheperaCommand::PositionGains { .. } => 'F',
            KheperaCommand::SetCounters { .. } => 'G',
            KheperaCommand::ReadCounters => 'H',
            KheperaCommand::SpeedProfile { .. } => 'J',
            KheperaCommand::ReadStatus => 'K',
            KheperaCommand::Led { .. } => 'L',
            KheperaCommand::ReadProximity => 'N',
            KheperaCommand::ReadAmbient => 'O',
        }
    }

    /// The command's line, without a line ending.
    pub fn encode(&self) -> String {
        let args: Vec<i64> = match *self {
            KheperaCommand::SpeedGains { kp, ki, kd }
            | KheperaCommand::PositionGains { kp, ki, kd } => vec![kp, ki, kd],
            KheperaCommand::MoveTo { left, right }
            | KheperaCommand::SetSpeed { left, right }
            | KheperaCommand::SetCounters { left, right } => vec![left, right],
            KheperaCommand::SpeedProfile { top, accel } => vec![top[0], accel[0], top[1], accel[1]],
            KheperaCommand::Led { led, action } => {
                let action = match action {
                    LedAction::Off => 0,
                    LedAction::On => 1,
                    LedAction::Toggle => 2,
                };
                vec![i64::from(led), action]
            }
            KheperaCommand::Version
            | KheperaCommand::ReadSpeed
            | KheperaCommand::ReadCounters
            | KheperaCommand::ReadStatus
            | KheperaCommand::ReadProximity
            | KheperaCommand::ReadAmbient => vec![],
        };
        join(self.letter(), &numbers(&args))
    }

    /// The command on one line (surrounding blanks ignored); `None` for an
    /// empty line, which the firmware ignores.
    pub fn parse(line: &str) -> Result<Option<KheperaCommand>, CommandError> {
        let mut parts = line.trim().split(',');
        let Some(letter) = parts.next().filter(|l| !l.is_empty()) else {
            return Ok(None);
        };
        let args: Vec<i64> = parts
            .map(|a| a.trim().parse())
            .collect::<Result<_, _>>()
            .map_err(|_| CommandError::BadArguments)?;
        use KheperaCommand as K;
        let command = match (letter, args.as_slice()) {
            ("A", &[kp, ki, kd]) => K::SpeedGains { kp, ki, kd },
            ("B", []) => K::Version,
            ("C", &[left, right]) => K::MoveTo { left, right },
            ("D", &[left, right]) => K::SetSpeed { left, right },
            ("E", []) => K::ReadSpeed,
            ("F", &[kp, ki, kd]) => K::PositionGains { kp, ki, kd },
            ("G", &[left, right]) => K::SetCounters { left, right },
            ("H", []) => K::ReadCounters,
            ("J", &[top_l, acc_l, top_r, acc_r]) => K::SpeedProfile {
                top: [top_l, top_r],
                accel: [acc_l, acc_r],
            },
            ("K", []) => K::ReadStatus,
            ("L", &[led @ 0..=1, action @ 0..=2]) => K::Led {
                led: led as u8,
                action: [LedAction::Off, LedAction::On, LedAction::Toggle][action as usize],
            },
            ("N", []) => K::ReadProximity,
            ("O", []) => K::ReadAmbient,
            ("A" | "B" | "C" | "D" | "E" | "F" | "G" | "H" | "J" | "K" | "L" | "N" | "O", _) => {
                return Err(CommandError::BadArguments);
            }
            _ => return Err(CommandError::Unknown),
        };
        Ok(Some(command))
    }
}

impl KheperaReply {
    /// The reply's lower-case letter.
    pub fn letter(&self) -> char {
        match self {
            KheperaReply::Done(letter) => *letter,
            KheperaReply::Version { .. } => 'b',
            KheperaReply::Speed(_) => 'e',
            KheperaReply::Counters(_) => 'h',
            KheperaReply::Status(_) => 'k',
            KheperaReply::Proximity(_) => 'n',
            KheperaReply::Ambient(_) => 'o',
            KheperaReply::Refused(_) => 'z',
        }
    }

    /// Whether this is what the robot answers to `command` when it carries it out.
    pub fn answers(&self, command: &KheperaCommand) -> bool {
        self.letter() == command.letter().to_ascii_lowercase()
    }

    /// The reply's line, without a line ending.
    pub fn encode(&self) -> String {
        let values = match self {
            KheperaReply::Done(_) => vec![],
            KheperaReply::Version { bios, protocol } => vec![bios.clone(), protocol.clone()],
            KheperaReply::Speed(pair) | KheperaReply::Counters(pair) => numbers(pair),
            KheperaReply::Status(motors) => motors
                .iter()
                .flat_map(|m| {
                    let mode = match m.mode {
                        MotorMode::Speed => 1,
                        MotorMode::Position => 0,
                    };
                    [i64::from(m.on_target), mode, m.error]
                })
                .map(|v| v.to_string())
                .collect(),
            KheperaReply::Proximity(values) | KheperaReply::Ambient(values) => numbers(values),
            KheperaReply::Refused(reason) => vec![reason.clone()],
        };
        join(self.letter(), &values)
    }

    /// The reply on one line (surrounding blanks ignored).
    pub fn parse(line: &str) -> Result<KheperaReply, MalformedReply> {
        let line = line.trim();
        let malformed = || MalformedReply(line.to_owned());
        let (letter, values) = match line.split_once(',') {
            Some((letter, values)) => (letter, Some(values)),
            None => (line, None),
        };
        let mut letters = letter.chars();
        let (Some(letter), None) = (letters.next(), letters.next()) else {
            return Err(malformed());
        };
        let ints = || -> Result<Vec<i64>, MalformedReply> {
            values
                .unwrap_or_default()
                .split(',')
                .map(|v| v.trim().parse().map_err(|_| malformed()))
                .collect()
        };
        let pair = || -> Result<[i64; 2], MalformedReply> {
            <[i64; 2]>::try_from(ints()?).map_err(|_| malformed())
        };
        let readings = || -> Result<Vec<u16>, MalformedReply> {
            values
                .unwrap_or_default()
                .split(',')
                .map(|v| v.trim().parse().map_err(|_| malformed()))
                .collect()
        };
        match (letter, values) {
            (l, None) if DONE_LETTERS.contains(l) => Ok(KheperaReply::Done(l)),
            ('b', Some(v)) => match v.split_once(',') {
                Some((bios, protocol)) => Ok(KheperaReply::Version {
                    bios: bios.trim().to_owned(),
                    protocol: protocol.trim().to_owned(),
                }),
                None => Err(malformed()),
            },
            ('e', Some(_)) => pair().map(KheperaReply::Speed),
            ('h', Some(_)) => pair().map(KheperaReply::Counters),
            ('k', Some(_)) => {
                let v = ints()?;
                let motor = |m: &[i64]| match *m {
                    [on_target @ 0..=1, mode @ 0..=1, error] => Ok(MotorStatus {
                        on_target: on_target == 1,
                        mode: if mode == 1 {
                            MotorMode::Speed
                        } else {
                            MotorMode::Position
                        },
                        error,
                    }),
                    _ => Err(malformed()),
                };
                if v.len() != 6 {
                    return Err(malformed());
                }
                Ok(KheperaReply::Status([motor(&v[..3])?, motor(&v[3..])?]))
            }
            ('n', Some(_)) => readings().map(KheperaReply::Proximity),
            ('o', Some(_)) => readings().map(KheperaReply::Ambient),
            ('z', Some(reason)) => Ok(KheperaReply::Refused(reason.trim().to_owned())),
            _ => Err(malformed()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn lines_as_the_firmware_writes_them() {
        assert_eq!(
            KheperaCommand::parse("D,10,-5\r"),
            Ok(Some(KheperaCommand::SetSpeed {
                left: 10,
                right: -5
            }))
        );
        assert_eq!(KheperaCommand::parse("  "), Ok(None));
        assert_eq!(KheperaCommand::parse("X"), Err(CommandError::Unknown));
        assert_eq!(
            KheperaCommand::parse("D,ten,10"),
            Err(CommandError::BadArguments)
        );
        assert_eq!(
            KheperaCommand::parse("D,10"),
            Err(CommandError::BadArguments)
        );
        assert_eq!(
            KheperaCommand::parse("L,2,1"),
            Err(CommandError::BadArguments)
        );
        assert_eq!(
            KheperaReply::parse("b,5.02,5.01\r\n"),
            Ok(KheperaReply::Version {
                bios: "5.02".into(),
                protocol: "5.01".into()
            })
        );
        assert_eq!(
            KheperaReply::parse("k,1,1,0,0,0,-12").map(|r| r.encode()),
            Ok("k,1,1,0,0,0,-12".into())
        );
        assert_eq!(
            KheperaReply::parse("z,Command not found"),
            Ok(KheperaReply::Refused("Command not found".into()))
        );
        for bad in ["", "h,1", "h,1,x", "b", "x", "dd", "n,-1", "k,1,1,0", "e"] {
            assert!(KheperaReply::parse(bad).is_err(), "{bad:?}");
        }
        let reply = KheperaReply::Counters([1, 2]);
        assert!(reply.answers(&KheperaCommand::ReadCounters));
        assert!(!reply.answers(&KheperaCommand::ReadSpeed));
    }

    fn command() -> impl Strategy<Value = KheperaCommand> {
        use KheperaCommand as K;
        let n = any::<i64>;
        let led = prop_oneof![
            Just(LedAction::Off),
            Just(LedAction::On),
            Just(LedAction::Toggle)
        ];
        prop_oneof![
            (n(), n(), n()).prop_map(|(kp, ki, kd)| K::SpeedGains { kp, ki, kd }),
            (n(), n(), n()).prop_map(|(kp, ki, kd)| K::PositionGains { kp, ki, kd }),
            (n(), n()).prop_map(|(left, right)| K::MoveTo { left, right }),
            (n(), n()).prop_map(|(left, right)| K::SetSpeed { left, right }),
            (n(), n()).prop_map(|(left, right)| K::SetCounters { left, right }),
            (any::<[i64; 2]>(), any::<[i64; 2]>())
                .prop_map(|(top, accel)| K::SpeedProfile { top, accel }),
            (0u8..=1, led).prop_map(|(led, action)| K::Led { led, action }),
            prop::sample::select(vec![
                K::Version,
                K::ReadSpeed,
                K::ReadCounters,
                K::ReadStatus,
                K::ReadProximity,
                K::ReadAmbient
            ]),
        ]
    }

    fn reply() -> impl Strategy<Value = KheperaReply> {
        use KheperaReply as R;
        let motor = (any::<bool>(), any::<bool>(), any::<i64>()).prop_map(|(on, speed, error)| {
            MotorStatus {
                on_target: on,
                mode: if speed {
                    MotorMode::Speed
                } else {
                    MotorMode::Position
                },
                error,
            }
        });
        let text = "[0-9A-Za-z.]{1,8}";
        prop_oneof![
            prop::sample::select(DONE_LETTERS.chars().collect::<Vec<_>>()).prop_map(R::Done),
            (text, text).prop_map(|(bios, protocol)| R::Version { bios, protocol }),
            any::<[i64; 2]>().prop_map(R::Speed),
            any::<[i64; 2]>().prop_map(R::Counters),
            [motor.clone(), motor].prop_map(R::Status),
            prop::collection::vec(0u16..=1023, 1..9).prop_map(R::Proximity),
            prop::collection::vec(0u16..=1023, 1..9).prop_map(R::Ambient),
            "[A-Za-z][A-Za-z ]*[a-z]".prop_map(R::Refused),
        ]
    }

    proptest! {
        /// Every command and reply reads back as itself from its line.
        #[test]
        fn lines_round_trip(c in command(), r in reply()) {
            prop_assert_eq!(KheperaCommand::parse(&c.encode()), Ok(Some(c)));
            prop_assert_eq!(KheperaReply::parse(&r.encode()), Ok(r.clone()));
            prop_assert_eq!(r.encode().chars().next(), Some(r.letter()));
        }

        /// No line, however garbled, makes either parser panic.
        #[test]
        fn any_line_parses_or_is_refused(line in ".{0,40}") {
            let _ = KheperaCommand::parse(&line);
            let _ = KheperaReply::parse(&line);
        }
    }
}
