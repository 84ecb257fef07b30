//! The real Khepera I/II on a serial line, behind the [`Robot`] trait.
//!
//! Each exchange is one command line and one reply, both in the protocol
//! of `vl-core`'s [`KheperaCommand`] and [`KheperaReply`]; a reply that is
//! not the command's (an unknown-command reply, a wrong letter, a garbled
//! line, silence past the timeout) is an error, never a value. The pose is
//! dead reckoning from the wheel encoders, starting at the pose the robot
//! was placed in.

use std::io::{Read, Write};
use std::time::Duration;

use serialport::{ClearBuffer, DataBits, FlowControl, Parity, SerialPort, StopBits};
use vl_core::{KheperaCommand, KheperaReply, MAX_PULSES_PER_PERIOD, Pose, RobotModel, WheelSpeeds};

use crate::drivers::{Robot, RobotError, RobotReading};

/// How long the robot has to answer one command.
const REPLY_TIMEOUT: Duration = Duration::from_millis(300);
/// A proximity reading this high means the body is touching something.
const TOUCHING: u16 = 1000;
/// The longest reply line the protocol has (`n,` and eight values) with room to spare.
const LONGEST_REPLY: usize = 256;

/// A Khepera answering the BIOS 5.x protocol on a serial port.
pub struct KheperaSerial {
    port: Box<dyn SerialPort>,
    model: RobotModel,
    pose: Pose,
    /// Encoder counts at the last read.
    counts: [i64; 2],
}

impl KheperaSerial {
    /// Opens `device` at `baud` (8 data bits, no parity, 2 stop bits),
    /// checks that a Khepera answers, and starts dead reckoning from `start`.
    pub fn open(
        device: &str,
        baud: u32,
        model: RobotModel,
        start: Pose,
    ) -> Result<KheperaSerial, RobotError> {
        let port = serialport::new(device, baud)
            .data_bits(DataBits::Eight)
            .parity(Parity::None)
            .stop_bits(StopBits::Two)
            .flow_control(FlowControl::None)
            .timeout(REPLY_TIMEOUT)
            .open()
            .map_err(|e| RobotError::Open {
                device: device.to_owned(),
                reason: e.to_string(),
            })?;
        let mut robot = KheperaSerial {
            port,
            model,
            pose: start,
            counts: [0; 2],
        };
        if let KheperaReply::Version { bios, .. } = robot.exchange(KheperaCommand::Version)? {
            tracing::info!("Khepera BIOS {bios} on {device}");
        }
        robot.exchange(KheperaCommand::SetSpeed { left: 0, right: 0 })?;
        robot.counts = robot.counters()?;
        Ok(robot)
    }

    /// Sends one command and returns the robot's reply to it.
    fn exchange(&mut self, command: KheperaCommand) -> Result<KheperaReply, RobotError> {
        let sent = command.encode();
        // A late reply to an earlier command must not pass for this one's.
        self.port.clear(ClearBuffer::Input).map_err(|e| {
            RobotError::Io(std::io::Error::other(format!("cannot clear the line: {e}")))
        })?;
        self.port
            .write_all(format!("{sent}\n").as_bytes())
            .and_then(|()| self.port.flush())
            .map_err(RobotError::Io)?;
        let mut line = Vec::new();
        let mut byte = [0u8; 1];
        loop {
            match self.port.read(&mut byte) {
                Ok(0) => {
                    return Err(RobotError::Io(std::io::ErrorKind::UnexpectedEof.into()));
                }
                Ok(_) if byte[0] == b'\n' => break,
                Ok(_) => line.push(byte[0]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    return Err(RobotError::Timeout {
                        sent,
                        waited_ms: REPLY_TIMEOUT.as_millis(),
                    });
                }
                Err(e) => return Err(RobotError::Io(e)),
            }
            if line.len() > LONGEST_REPLY {
                break;
            }
        }
        let got = String::from_utf8_lossy(&line).trim().to_owned();
        match KheperaReply::parse(&got) {
            Ok(reply) if reply.answers(&command) => Ok(reply),
            _ => Err(RobotError::Garbled { sent, got }),
        }
    }

    /// Two numbers the robot answers `command` with (E, H).
    fn pair(&mut self, command: KheperaCommand) -> Result<[i64; 2], RobotError> {
        match self.exchange(command)? {
            KheperaReply::Speed(pair) | KheperaReply::Counters(pair) => Ok(pair),
            other => Err(RobotError::Garbled {
                sent: command.encode(),
                got: other.encode(),
            }),
        }
    }

    /// The wheels' speeds now (`E`), without the rest of a reading: what
    /// characterising the speed controller samples as fast as it can.
    pub fn wheel_speeds(&mut self) -> Result<WheelSpeeds, RobotError> {
        let [left, right] = self.pair(KheperaCommand::ReadSpeed)?;
        Ok(WheelSpeeds {
            left_mm_s: self.model.speed_mm_s(left),
            right_mm_s: self.model.speed_mm_s(right),
        })
    }

    fn counters(&mut self) -> Result<[i64; 2], RobotError> {
        self.pair(KheperaCommand::ReadCounters)
    }

    /// One proximity value per sensor of the model.
    fn proximity(&mut self) -> Result<Vec<u16>, RobotError> {
        let command = KheperaCommand::ReadProximity;
        match self.exchange(command)? {
            KheperaReply::Proximity(values) if values.len() == self.model.sensors.len() => {
                Ok(values.into_iter().map(|v| v.min(1023)).collect())
            }
            other => Err(RobotError::Garbled {
                sent: command.encode(),
                got: other.encode(),
            }),
        }
    }

    /// mm/s to the firmware's pulses per 10 ms, within its limit.
    fn pulses(&self, mm_s: f64) -> i64 {
        self.model
            .pulses_per_period(mm_s)
            .clamp(-MAX_PULSES_PER_PERIOD, MAX_PULSES_PER_PERIOD)
    }
}

impl Robot for KheperaSerial {
    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), RobotError> {
        let wheels = self.model.clamp(wheels);
        let command = KheperaCommand::SetSpeed {
            left: self.pulses(wheels.left_mm_s),
            right: self.pulses(wheels.right_mm_s),
        };
        self.exchange(command).map(drop)
    }

    fn read(&mut self) -> Result<RobotReading, RobotError> {
        let counts = self.counters()?;
        let per = self.model.mm_per_pulse;
        // The wheels' travel since the last read moves the body along one arc.
        let travel = WheelSpeeds {
            left_mm_s: (counts[0] - self.counts[0]) as f64 * per,
            right_mm_s: (counts[1] - self.counts[1]) as f64 * per,
        };
        self.pose = self.pose.advance(travel, self.model.wheel_base_mm, 1.0);
        self.counts = counts;
        let speed = self.pair(KheperaCommand::ReadSpeed)?;
        let proximity = self.proximity()?;
        Ok(RobotReading {
            pose: self.pose,
            wheels: WheelSpeeds {
                left_mm_s: self.model.speed_mm_s(speed[0]),
                right_mm_s: self.model.speed_mm_s(speed[1]),
            },
            contact: proximity.iter().any(|&v| v >= TOUCHING),
            proximity,
        })
    }
}
