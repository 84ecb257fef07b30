//! The real Khepera I/II on a serial line, behind the [`Robot`] trait.
//!
//! Each exchange is one command line and one reply whose first letter must
//! be the command's in lower case; anything else (an unknown-command
//! reply, a wrong letter, silence past the timeout) is an error, never a
//! value. The pose is dead reckoning from the wheel encoders, starting at
//! the pose the robot was placed in.

use std::io::{Read, Write};
use std::time::Duration;

use serialport::{ClearBuffer, DataBits, FlowControl, Parity, SerialPort, StopBits};
use vl_core::robot::{MAX_PULSES_PER_PERIOD, Pose, RobotModel, WheelSpeeds};

use crate::drivers::{Robot, RobotError, RobotReading};

/// How long the robot has to answer one command.
const REPLY_TIMEOUT: Duration = Duration::from_millis(300);
/// A proximity reading this high means the body is touching something.
const TOUCHING: u16 = 1000;

/// A Khepera answering the BIOS 5.x protocol on a serial port.
pub struct KheperaSerial {
    port: Box<dyn SerialPort>,
    path: String,
    model: RobotModel,
    pose: Pose,
    /// Encoder counts at the last read.
    counts: [i64; 2],
}

impl KheperaSerial {
    /// Opens `path` at `baud` (8 data bits, no parity, 2 stop bits), checks
    /// that a Khepera answers, and starts dead reckoning from `start`.
    pub fn open(
        path: &str,
        baud: u32,
        model: RobotModel,
        start: Pose,
    ) -> Result<KheperaSerial, RobotError> {
        let port = serialport::new(path, baud)
            .data_bits(DataBits::Eight)
            .parity(Parity::None)
            .stop_bits(StopBits::Two)
            .flow_control(FlowControl::None)
            .timeout(REPLY_TIMEOUT)
            .open()
            .map_err(|e| RobotError(format!("cannot open {path}: {e}")))?;
        let mut robot = KheperaSerial {
            port,
            path: path.to_owned(),
            model,
            pose: start,
            counts: [0; 2],
        };
        let version = robot.exchange("B")?;
        tracing::info!("Khepera BIOS {version} on {path}");
        robot.exchange("D,0,0")?;
        robot.counts = robot.counters()?;
        Ok(robot)
    }

    /// Sends one command and returns its reply's values (after `x,`).
    fn exchange(&mut self, command: &str) -> Result<String, RobotError> {
        let fault = |what: String| RobotError(format!("{} on {}: {what}", command, self.path));
        // A late reply to an earlier command must not pass for this one's.
        self.port
            .clear(ClearBuffer::Input)
            .map_err(|e| fault(format!("cannot clear the line: {e}")))?;
        self.port
            .write_all(format!("{command}\n").as_bytes())
            .and_then(|()| self.port.flush())
            .map_err(|e| fault(format!("cannot send: {e}")))?;
        let mut line = Vec::new();
        let mut byte = [0u8; 1];
        loop {
            match self.port.read(&mut byte) {
                Ok(0) => return Err(fault("the line closed".into())),
                Ok(_) if byte[0] == b'\n' => break,
                Ok(_) => line.push(byte[0]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    return Err(fault(format!(
                        "no reply within {} ms",
                        REPLY_TIMEOUT.as_millis()
                    )));
                }
                Err(e) => return Err(fault(format!("cannot read: {e}"))),
            }
            if line.len() > 256 {
                return Err(fault("a reply longer than any the protocol has".into()));
            }
        }
        let reply = String::from_utf8_lossy(&line).trim().to_owned();
        let expected = command[..1].to_lowercase();
        match reply.split_once(',') {
            Some((letter, values)) if letter == expected => Ok(values.to_owned()),
            None if reply == expected => Ok(String::new()),
            _ => Err(fault(format!("unexpected reply '{reply}'"))),
        }
    }

    /// The reply's values as integers, exactly `n` of them.
    fn numbers(&mut self, command: &str, n: usize) -> Result<Vec<i64>, RobotError> {
        let values = self.exchange(command)?;
        let parsed: Result<Vec<i64>, _> = values.split(',').map(|v| v.trim().parse()).collect();
        match parsed {
            Ok(v) if v.len() == n => Ok(v),
            _ => Err(RobotError(format!(
                "{command} on {}: expected {n} integers, got '{values}'",
                self.path
            ))),
        }
    }

    fn counters(&mut self) -> Result<[i64; 2], RobotError> {
        let v = self.numbers("H", 2)?;
        Ok([v[0], v[1]])
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
        let command = format!(
            "D,{},{}",
            self.pulses(wheels.left_mm_s),
            self.pulses(wheels.right_mm_s)
        );
        self.exchange(&command).map(drop)
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
        let speed = self.numbers("E", 2)?;
        let proximity: Vec<u16> = self
            .numbers("N", self.model.sensors.len())?
            .into_iter()
            .map(|v| v.clamp(0, 1023) as u16)
            .collect();
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
