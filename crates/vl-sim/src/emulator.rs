//! A Khepera on a pseudo-terminal: opens a pty, and answers whatever a
//! program writes to its device path as a real Khepera on a serial cable
//! would, backed by the simulated robot moving in real time. The Host's
//! serial driver is tested against it end to end.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use thiserror::Error;

use crate::khepera::Khepera;

/// The longest command line the emulator holds while waiting for its end.
const MAX_LINE: usize = 256;
/// Bits on the wire per character: start, 8 data, 2 stop (Khepera: 8N2).
const BITS_PER_CHAR: f64 = 11.0;

#[derive(Debug, Error)]
pub enum EmulatorError {
    #[error("cannot open a pseudo-terminal: {0}")]
    Pty(#[from] serialport::Error),
    #[error("cannot link {link} to {device}: {source}")]
    Link {
        link: PathBuf,
        device: String,
        source: std::io::Error,
    },
    #[error("the pseudo-terminal failed: {0}")]
    Io(#[from] std::io::Error),
}

/// The emulated port's line settings.
#[derive(Debug, Clone, Copy)]
pub struct PortSettings {
    pub baud: u32,
    /// Take as long over each command and reply as its characters take at
    /// `baud`: a command is acted on only once its last character is in.
    pub timing: bool,
    /// Print each command line received, with the ms since the start.
    pub log_commands: bool,
    /// Print the robot's true pose and its contacts so far every 50 ms of
    /// the robot's clock (a camera's rate), as `truth T_S X_MM Y_MM THETA_RAD
    /// CONTACTS`, and after it `leash T_S REMAINING_MM TARGET_L_MM
    /// TARGET_R_MM` (how far the wheels may still go to their position
    /// targets, the larger, and the targets as each wheel's travel) or
    /// `leash T_S none` under speed control: what a test or bench judges a
    /// run by (a real robot has no such line).
    pub truth: bool,
}

/// An emulated Khepera waiting on a pty.
pub struct Emulator {
    khepera: Khepera,
    master: TTYPort,
    /// Kept open so the master side survives clients closing and reopening the device.
    _slave: TTYPort,
    device: String,
    line: PortSettings,
}

impl Emulator {
    /// Opens a pty for `khepera`; `link`, if given, becomes a symlink to its device.
    pub fn open(
        khepera: Khepera,
        line: PortSettings,
        link: Option<&Path>,
    ) -> Result<Emulator, EmulatorError> {
        // The slave end stays open but unlocked, so a client can open (and lock) the device.
        let (mut master, slave) = TTYPort::pair()?;
        master.set_timeout(Duration::from_millis(20))?;
        let device = slave.name().unwrap_or_default();
        if let Some(link) = link {
            let _ = std::fs::remove_file(link);
            std::os::unix::fs::symlink(&device, link).map_err(|source| EmulatorError::Link {
                link: link.to_owned(),
                device: device.clone(),
                source,
            })?;
        }
        Ok(Emulator {
            khepera,
            master,
            _slave: slave,
            device,
            line,
        })
    }

    /// The device path a client opens.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// Answers commands until the pty fails; the simulated robot follows the wall clock.
    pub fn run(&mut self) -> Result<(), EmulatorError> {
        let started = Instant::now();
        let mut pending: Vec<u8> = Vec::new();
        let mut buf = [0u8; 256];
        let mut told = f64::NEG_INFINITY;
        loop {
            if self.line.truth && self.khepera.world().time_s() >= told + 0.05 {
                let world = self.khepera.world();
                told = world.time_s();
                let pose = world.pose();
                let travel = world.wheel_travel_mm();
                let leash = world.targets_mm().map_or("none".to_owned(), |t| {
                    let ahead = (t[0] - travel[0]).abs().max((t[1] - travel[1]).abs());
                    format!("{ahead:.1} {:.1} {:.1}", t[0], t[1])
                });
                // Nobody reading is no reason to stop answering the robot's line.
                let mut out = std::io::stdout().lock();
                let _ = writeln!(
                    out,
                    "truth {:.2} {:.1} {:.1} {:.3} {}\nleash {told:.2} {leash}",
                    told,
                    pose.x_mm,
                    pose.y_mm,
                    pose.theta_rad,
                    world.collisions()
                )
                .and_then(|()| out.flush());
            }
            let n = match self.master.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => 0,
                Err(e) => return Err(e.into()),
            };
            pending.extend_from_slice(&buf[..n]);
            // No command is this long: a line without an end is noise, dropped.
            if pending.len() > MAX_LINE && !pending.iter().any(|&b| b == b'\r' || b == b'\n') {
                pending.clear();
                self.send("z,Command not found")?;
            }
            self.catch_up(started.elapsed().as_secs_f64());
            while let Some(end) = pending.iter().position(|&b| b == b'\r' || b == b'\n') {
                let line: Vec<u8> = pending.drain(..=end).collect();
                let text = String::from_utf8_lossy(&line[..line.len() - 1]).into_owned();
                // The pty delivers the line at once; a cable takes its time.
                self.wire_time(line.len());
                self.catch_up(started.elapsed().as_secs_f64());
                if self.line.log_commands && !text.trim().is_empty() {
                    println!(
                        "{:.1} {}",
                        started.elapsed().as_secs_f64() * 1e3,
                        text.trim()
                    );
                    use std::io::Write as _;
                    let _ = std::io::stdout().flush();
                }
                if let Some(reply) = self.khepera.handle(&text) {
                    self.send(&reply)?;
                }
            }
        }
    }

    /// Steps the simulated robot as far as its clock can go without
    /// passing `seconds`: what it reports has happened, not what is about to.
    fn catch_up(&mut self, seconds: f64) {
        while self.khepera.world().time_s() + crate::STEP_S <= seconds {
            self.khepera.step();
        }
    }

    /// Waits as long as `chars` characters take on the emulated line.
    fn wire_time(&self, chars: usize) {
        if self.line.timing {
            let seconds = chars as f64 * BITS_PER_CHAR / f64::from(self.line.baud.max(1));
            std::thread::sleep(Duration::from_secs_f64(seconds));
        }
    }

    fn send(&mut self, reply: &str) -> Result<(), EmulatorError> {
        let wire = format!("{reply}\r\n");
        self.wire_time(wire.len());
        self.master.write_all(wire.as_bytes())?;
        self.master.flush()?;
        Ok(())
    }
}
