//! The real Khepera I/II on a serial line, behind the [`Robot`] trait.
//!
//! Each exchange is one command line and one reply, both in the protocol
//! of `vl-core`'s [`KheperaCommand`] and [`KheperaReply`]; a reply that is
//! not the command's (an unknown-command reply, a wrong letter, a garbled
//! line, silence past the timeout) is an error, never a value. The pose is
//! dead reckoning from the wheel encoders, starting at the pose the robot
//! was placed in.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use vl_core::{
    KheperaCommand, KheperaReply, Leash, MAX_PULSES_PER_PERIOD, Pose, Priority, RobotModel,
    WheelSpeeds,
};

use crate::drivers::{Robot, RobotError, RobotReading};
use crate::line::{GuardedLine, Line, SerialLine};

/// Replies to earlier commands a robot may still send when it is reached again.
const STALE_REPLIES: usize = 3;
/// A proximity reading this high means the body is touching something.
const TOUCHING: u16 = 1000;

/// How a Khepera's line is opened, and opened again after it is lost.
#[derive(Debug, Clone)]
enum Opening {
    /// The port itself.
    Direct { device: String, baud: u32 },
    /// A guard process, the program given, holding the port.
    Guarded {
        program: PathBuf,
        device: String,
        baud: u32,
    },
}

impl Opening {
    fn open(&self) -> Result<Box<dyn Line>, RobotError> {
        Ok(match self {
            Opening::Direct { device, baud } => Box::new(SerialLine::open(device, *baud)?),
            Opening::Guarded {
                program,
                device,
                baud,
            } => Box::new(GuardedLine::spawn(program, device, *baud)?),
        })
    }

    fn device(&self) -> &str {
        match self {
            Opening::Direct { device, .. } | Opening::Guarded { device, .. } => device,
        }
    }
}

/// A Khepera answering the BIOS 5.x protocol on a serial line.
pub struct KheperaSerial {
    line: Box<dyn Line>,
    opening: Opening,
    model: RobotModel,
    pose: Pose,
    /// Encoder counts at the last read.
    counts: [i64; 2],
    /// How long the last drive's exchanges took.
    command_latency: Duration,
    /// The top speeds the profile was last set to (`J`), if it is known.
    profile: Option<[i64; 2]>,
}

impl KheperaSerial {
    /// Opens `device` at `baud` directly, checks that a Khepera answers,
    /// and starts dead reckoning from `start`.
    pub fn open(
        device: &str,
        baud: u32,
        model: RobotModel,
        start: Pose,
    ) -> Result<KheperaSerial, RobotError> {
        let opening = Opening::Direct {
            device: device.to_owned(),
            baud,
        };
        KheperaSerial::with(opening, model, start)
    }

    /// The same through a guard process — `program serial-guard` — that
    /// stops the robot if this process dies: what the Host drives through.
    pub fn guarded(
        program: PathBuf,
        device: &str,
        baud: u32,
        model: RobotModel,
        start: Pose,
    ) -> Result<KheperaSerial, RobotError> {
        let opening = Opening::Guarded {
            program,
            device: device.to_owned(),
            baud,
        };
        KheperaSerial::with(opening, model, start)
    }

    fn with(opening: Opening, model: RobotModel, start: Pose) -> Result<KheperaSerial, RobotError> {
        // A guard left by a Host that just died lets go of the port within
        // its exit time: wait that long for it before giving up.
        let given_up = Instant::now() + Duration::from_secs(2);
        let line = loop {
            match opening.open() {
                Ok(line) => break line,
                Err(RobotError::Open { .. }) if Instant::now() < given_up => {
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(e) => return Err(e),
            }
        };
        let mut robot = KheperaSerial {
            line,
            opening,
            model,
            pose: start,
            counts: [0; 2],
            command_latency: Duration::ZERO,
            profile: None,
        };
        robot.greet()?;
        Ok(robot)
    }

    /// Checks that a Khepera answers, stops it, and takes its counters as
    /// the origin of dead reckoning.
    fn greet(&mut self) -> Result<(), RobotError> {
        // A robot back from a pause may still answer what was asked before
        // it: a few replies that are not this one's are let go by.
        let mut version = self.exchange(KheperaCommand::Version);
        for _ in 0..STALE_REPLIES {
            if !matches!(version, Err(RobotError::Garbled { .. })) {
                break;
            }
            version = self.exchange(KheperaCommand::Version);
        }
        if let KheperaReply::Version { bios, .. } = version? {
            tracing::info!("Khepera BIOS {bios} on {}", self.opening.device());
        }
        self.exchange(KheperaCommand::SetSpeed { left: 0, right: 0 })?;
        self.profile = None;
        self.counts = self.counters()?;
        Ok(())
    }

    /// Sends one command and returns the robot's reply to it.
    fn exchange(&mut self, command: KheperaCommand) -> Result<KheperaReply, RobotError> {
        let sent = command.encode();
        let got = self.line.exchange(&sent)?;
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

    /// Wheel speeds by the speed controller (`D`): they hold until the next
    /// command, whatever becomes of the Host. Only for characterising the
    /// speed controller, with someone watching; a lab drives by leashes.
    pub fn set_speed(&mut self, wheels: WheelSpeeds) -> Result<(), RobotError> {
        let wheels = self.model.clamp(wheels);
        self.profile = None;
        let command = KheperaCommand::SetSpeed {
            left: self.pulses(wheels.left_mm_s),
            right: self.pulses(wheels.right_mm_s),
        };
        self.exchange(command).map(drop)
    }

    fn leash(&mut self, leash: &Leash) -> Result<(), RobotError> {
        if leash.is_stop() {
            self.profile = None;
            return self
                .exchange(KheperaCommand::SetSpeed { left: 0, right: 0 })
                .map(drop);
        }
        let top = leash.top.map(|t| t.abs().min(MAX_PULSES_PER_PERIOD));
        if self.profile != Some(top) {
            let accel = self.model.profile_accel();
            // Until it is answered the profile is not known.
            self.profile = None;
            self.exchange(KheperaCommand::SpeedProfile {
                top,
                accel: [accel; 2],
            })?;
            self.profile = Some(top);
        }
        let limit = i64::from(i32::MAX);
        let target = |i: usize| (self.counts[i] + leash.reach[i]).clamp(-limit, limit);
        self.exchange(KheperaCommand::MoveTo {
            left: target(0),
            right: target(1),
        })
        .map(drop)
    }
}

impl Robot for KheperaSerial {
    fn model(&self) -> &RobotModel {
        &self.model
    }

    /// A leash is the profile's top speeds (`J`, sent only when they
    /// change, before the targets, so a Host stopped between the two
    /// leaves the old targets) and the targets (`C`); a stop is `D,0,0`.
    fn drive(&mut self, leash: &Leash) -> Result<(), RobotError> {
        let sent = Instant::now();
        let result = self.leash(leash);
        self.command_latency = sent.elapsed();
        result
    }

    fn command_latency(&self) -> Duration {
        self.command_latency
    }

    fn guard_priority(&self) -> Option<Priority> {
        self.line.guard_priority()
    }

    /// Opens the line afresh; dead reckoning carries on from the last pose.
    /// The old line goes first: a guard still holding the port would lock
    /// the new one out.
    fn reconnect(&mut self) -> Result<(), RobotError> {
        self.line = Box::new(Closed);
        self.line = self.opening.open()?;
        self.greet()
    }

    fn read(&mut self) -> Result<RobotReading, RobotError> {
        // The counters are sampled after this: the pose is at most this old.
        let taken = Instant::now();
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
            travel_mm: counts.map(|c| c as f64 * per),
            odometry: self.pose,
            wheels: WheelSpeeds {
                left_mm_s: self.model.speed_mm_s(speed[0]),
                right_mm_s: self.model.speed_mm_s(speed[1]),
            },
            contact: proximity.iter().any(|&v| v >= TOUCHING),
            proximity,
            taken,
        })
    }
}

/// A line that is not there, between losing one and opening the next.
struct Closed;

impl Line for Closed {
    fn exchange(&mut self, _: &str) -> Result<String, RobotError> {
        Err(RobotError::Io(std::io::Error::other("the line is closed")))
    }
}
