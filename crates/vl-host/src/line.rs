//! The serial line to a robot: one command line out, one reply line back.
//! Either the port itself ([`SerialLine`]), or a guard process that holds
//! the port for the Host ([`GuardedLine`]): when the Host's end of the pipe
//! closes — a crash, `kill -9`, the kernel's OOM killer — the guard stops
//! the robot at once and exits; when the Host goes silent (frozen), it
//! stops the robot too.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use serialport::{ClearBuffer, DataBits, FlowControl, Parity, SerialPort, StopBits};

use vl_core::Priority;

use crate::drivers::RobotError;

/// How long the robot has to answer one command.
pub(crate) const REPLY_TIMEOUT: Duration = Duration::from_millis(300);
/// The longest reply line the protocol has (`n,` and eight values), with room to spare.
const LONGEST_REPLY: usize = 256;
/// The command that stops both wheels.
const STOP: &str = "D,0,0";
/// A Host that sends nothing for this long is taken to be stuck: the guard
/// stops the robot (the Host reads it every control period).
const SILENCE: Duration = Duration::from_millis(500);
/// How long a reply already on its way may take to be passed on.
const LATE_REPLY: Duration = Duration::from_millis(100);
/// How long a starting guard has to open the port.
const GUARD_START: Duration = Duration::from_secs(3);
/// How long a guard told to go has to stop the robot (one exchange, which
/// may time out) and exit before it is killed.
const GUARD_EXIT: Duration = Duration::from_secs(1);

/// One exchange at a time with a robot.
pub(crate) trait Line: Send {
    /// Sends `command` (without a line ending) and returns the reply line.
    fn exchange(&mut self, command: &str) -> Result<String, RobotError>;
    /// The priority of the guard process holding the port, if one does.
    fn guard_priority(&self) -> Option<Priority> {
        None
    }
}

/// A robot's serial port, opened directly.
pub(crate) struct SerialLine {
    port: Box<dyn SerialPort>,
}

impl SerialLine {
    /// Opens `device` at `baud`: 8 data bits, no parity, 2 stop bits.
    pub(crate) fn open(device: &str, baud: u32) -> Result<SerialLine, RobotError> {
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
        Ok(SerialLine { port })
    }

    /// Sends `command` without waiting for its reply.
    fn send(&mut self, command: &str) -> Result<(), RobotError> {
        self.port
            .write_all(format!("{command}\n").as_bytes())
            .and_then(|()| self.port.flush())
            .map_err(RobotError::Io)
    }
}

impl Line for SerialLine {
    fn exchange(&mut self, command: &str) -> Result<String, RobotError> {
        // A late reply to an earlier command must not pass for this one's.
        self.port.clear(ClearBuffer::Input).map_err(|e| {
            RobotError::Io(std::io::Error::other(format!("cannot clear the line: {e}")))
        })?;
        self.send(command)?;
        let mut line = Vec::new();
        let mut byte = [0u8; 1];
        loop {
            match self.port.read(&mut byte) {
                Ok(0) => return Err(RobotError::Io(std::io::ErrorKind::UnexpectedEof.into())),
                Ok(_) if byte[0] == b'\n' => break,
                Ok(_) => line.push(byte[0]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    return Err(RobotError::Timeout {
                        sent: command.to_owned(),
                        waited_ms: REPLY_TIMEOUT.as_millis(),
                    });
                }
                Err(e) => return Err(RobotError::Io(e)),
            }
            if line.len() > LONGEST_REPLY {
                break;
            }
        }
        Ok(String::from_utf8_lossy(&line).trim().to_owned())
    }
}

/// The Host's end of a guard process holding the port.
pub(crate) struct GuardedLine {
    guard: Child,
    to_guard: Option<ChildStdin>,
    replies: mpsc::Receiver<String>,
    /// What the guard got of the processor, as it said when ready.
    priority: Priority,
}

/// What the guard says when it holds the port, followed by its priority.
const GUARD_READY: &str = "ready";
/// What the guard says instead of a reply when the robot gave none.
const GUARD_TIMEOUT: &str = "!timeout";
const GUARD_ERROR: &str = "!error ";

impl GuardedLine {
    /// Starts `program serial-guard --port DEVICE --baud BAUD` (the `vl`
    /// binary) and waits for it to hold the port.
    pub(crate) fn spawn(
        program: &Path,
        device: &str,
        baud: u32,
    ) -> Result<GuardedLine, RobotError> {
        let mut guard = Command::new(program)
            .args([
                "serial-guard",
                "--port",
                device,
                "--baud",
                &baud.to_string(),
            ])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| RobotError::Open {
                device: device.to_owned(),
                reason: format!("cannot start the serial guard {}: {e}", program.display()),
            })?;
        let stdout = guard.stdout.take().expect("piped stdout");
        let (tx, replies) = mpsc::channel();
        std::thread::Builder::new()
            .name("vl-guard-replies".into())
            .spawn(move || {
                // The control loop waits on it for every reply.
                crate::priority::raise_for_control("guard's reply reader");
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            })
            .map_err(RobotError::Io)?;
        let mut line = GuardedLine {
            to_guard: guard.stdin.take(),
            guard,
            replies,
            priority: Priority::Normal,
        };
        match line.replies.recv_timeout(GUARD_START) {
            Ok(ready) if ready.split(' ').next() == Some(GUARD_READY) => {
                let said = ready[GUARD_READY.len()..].trim();
                line.priority = serde_json::from_str(said).unwrap_or_default();
                Ok(line)
            }
            Ok(said) => Err(RobotError::Open {
                device: device.to_owned(),
                reason: said.strip_prefix(GUARD_ERROR).unwrap_or(&said).to_owned(),
            }),
            Err(_) => {
                let _ = line.guard.kill();
                Err(RobotError::Open {
                    device: device.to_owned(),
                    reason: "the serial guard did not start".into(),
                })
            }
        }
    }
}

impl Line for GuardedLine {
    fn guard_priority(&self) -> Option<Priority> {
        Some(self.priority)
    }

    fn exchange(&mut self, command: &str) -> Result<String, RobotError> {
        // A reply that came after its exchange gave up is not this one's.
        while self.replies.try_recv().is_ok() {}
        let ended = || RobotError::Io(std::io::Error::other("the serial guard has ended"));
        let to_guard = self.to_guard.as_mut().ok_or_else(ended)?;
        to_guard
            .write_all(format!("{command}\n").as_bytes())
            .and_then(|()| to_guard.flush())
            .map_err(|_| ended())?;
        // The guard answers within its own reply timeout. A Host that was
        // itself stopped meanwhile may find the time up before its reader
        // passed the reply on: it looks once more before giving up.
        let reply = match self.replies.recv_timeout(REPLY_TIMEOUT * 2) {
            Err(mpsc::RecvTimeoutError::Timeout) => self.replies.recv_timeout(LATE_REPLY),
            other => other,
        }
        .map_err(|e| match e {
            mpsc::RecvTimeoutError::Timeout => RobotError::Timeout {
                sent: command.to_owned(),
                waited_ms: (REPLY_TIMEOUT * 2 + LATE_REPLY).as_millis(),
            },
            mpsc::RecvTimeoutError::Disconnected => ended(),
        })?;
        if reply == GUARD_TIMEOUT {
            return Err(RobotError::Timeout {
                sent: command.to_owned(),
                waited_ms: REPLY_TIMEOUT.as_millis(),
            });
        }
        if let Some(why) = reply.strip_prefix(GUARD_ERROR) {
            return Err(RobotError::Io(std::io::Error::other(why.to_owned())));
        }
        Ok(reply)
    }
}

impl Drop for GuardedLine {
    fn drop(&mut self) {
        // Closing its input is what tells the guard to stop the robot and go;
        // one stuck on a silent robot is not waited for past its last stop.
        drop(self.to_guard.take());
        let deadline = std::time::Instant::now() + GUARD_EXIT;
        while std::time::Instant::now() < deadline {
            if !matches!(self.guard.try_wait(), Ok(None)) {
                return;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = self.guard.kill();
        let _ = self.guard.wait();
    }
}

/// The guard process (`vl serial-guard`): holds the port, relays the
/// Host's command lines and the robot's replies, and stops the robot when
/// the Host's end closes (then exits) or goes silent. What goes wrong is
/// said to the Host on the pipe, so an error returned here needs no more
/// telling.
pub fn run_guard(device: &str, baud: u32) -> Result<(), RobotError> {
    // A Host that dies mid-exchange leaves the reply nowhere to go: the
    // guard must see that as an error and stop the robot, not be killed
    // by SIGPIPE as a filter would be.
    #[cfg(target_os = "linux")]
    // SAFETY: setting one signal's action before the guard starts any thread.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
    let mut out = std::io::stdout().lock();
    let mut say = |line: &str| -> Result<(), RobotError> {
        writeln!(out, "{line}")
            .and_then(|()| out.flush())
            .map_err(RobotError::Io)
    };
    let mut line = match SerialLine::open(device, baud) {
        Ok(line) => line,
        Err(RobotError::Open { reason, .. }) => {
            say(&format!("{GUARD_ERROR}{reason}"))?;
            return Err(RobotError::Io(std::io::Error::other(reason)));
        }
        Err(e) => {
            say(&format!("{GUARD_ERROR}{e}"))?;
            return Err(e);
        }
    };
    // Its one job is to stop the robot in time: it asks to run first.
    let priority = crate::priority::raise_for_control("serial guard");
    let priority = serde_json::to_string(&priority).unwrap_or_default();
    say(&format!("{GUARD_READY} {priority}"))?;
    let (tx, commands) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        let mut input = BufReader::new(std::io::stdin().lock());
        let mut text = String::new();
        loop {
            text.clear();
            // A line is at most a command's length; anything longer is cut.
            match input
                .by_ref()
                .take(LONGEST_REPLY as u64)
                .read_line(&mut text)
            {
                Ok(0) | Err(_) => break,
                Ok(_) => {
                    if tx.send(text.trim().to_owned()).is_err() {
                        break;
                    }
                }
            }
        }
    });
    let mut silent_stop = false;
    loop {
        match commands.recv_timeout(SILENCE) {
            Ok(command) => {
                silent_stop = false;
                let reply = match line.exchange(&command) {
                    Ok(reply) => reply,
                    Err(RobotError::Timeout { .. }) => GUARD_TIMEOUT.to_owned(),
                    // The Host says what failed; the guard passes the cause.
                    Err(RobotError::Io(e)) => format!("{GUARD_ERROR}{e}"),
                    Err(e) => format!("{GUARD_ERROR}{e}"),
                };
                if let Err(e) = say(&reply) {
                    // The Host died while the robot answered: stop it all the same.
                    let _ = line.send(STOP);
                    return Err(e);
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if !silent_stop {
                    silent_stop = true;
                    let _ = line.exchange(STOP);
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                // The Host is gone: stop the robot, whatever it was doing,
                // and go at once (a robot that does not answer cannot be
                // stopped any better by waiting for it).
                let _ = line.send(STOP);
                return Ok(());
            }
        }
    }
}
