//! A user's own wheel controller (issue 58): what the lab tells it every
//! control period and what it answers, as interface version 1 lays them
//! out in its memory, and the trait a sandbox running one implements, so
//! the twin's forecast and the Host drive it alike without knowing how it
//! runs. (The lab's session controllers, synthesised for its nets, are a
//! different thing: see `design`.)

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::{Fingerprint, Point, Pose, SyntaxError, WheelSpeeds};

/// The interface version a module says it speaks (`vl_abi`).
pub const ABI_VERSION: i32 = 1;
/// The observation is this many little-endian f64s; those past the ones
/// version 1 names are 0, kept for later versions.
pub const OBSERVATION_WORDS: usize = 32;
/// The command is this many f64s: left and right wheel speed, mm/s.
pub const COMMAND_WORDS: usize = 2;
/// A controller's steps come this often, s: 50 Hz, every other period of
/// the Host's control loop.
pub const STEP_PERIOD_S: f64 = 0.02;

/// The largest module a user may hand in, bytes.
pub const MAX_MODULE_BYTES: usize = 2 << 20;

/// A module by the SHA-256 of its file: what a definition, a recording and
/// a regrade name it by.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(try_from = "String", into = "String")]
#[schemars(with = "String")]
pub struct ModuleHash(pub [u8; 32]);

/// The same digest, hex and parsing as a certificate's fingerprint.
impl ModuleHash {
    pub fn of(file: &[u8]) -> ModuleHash {
        ModuleHash(Fingerprint::of(file).0)
    }
}

/// 64 lowercase hex digits.
impl std::fmt::Display for ModuleHash {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        Fingerprint(self.0).fmt(f)
    }
}

impl std::fmt::Debug for ModuleHash {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ModuleHash({self})")
    }
}

impl std::str::FromStr for ModuleHash {
    type Err = SyntaxError;

    fn from_str(text: &str) -> Result<ModuleHash, SyntaxError> {
        text.parse().map(|Fingerprint(digest)| ModuleHash(digest))
    }
}

impl TryFrom<String> for ModuleHash {
    type Error = SyntaxError;

    fn try_from(text: String) -> Result<ModuleHash, SyntaxError> {
        text.parse()
    }
}

impl From<ModuleHash> for String {
    fn from(hash: ModuleHash) -> String {
        hash.to_string()
    }
}

/// What a controller is told before each step.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Time since the run's start, s.
    pub t_s: f64,
    /// The Host's pose estimate.
    pub pose: Pose,
    /// How far the robot may be from it, mm.
    pub uncertainty_mm: f64,
    /// The wheels' measured speeds.
    pub wheels: WheelSpeeds,
    /// The definition's goal, if it has one.
    pub goal: Option<Point>,
    /// The 8 proximity readings (fewer are padded with 0).
    pub proximity: [f64; 8],
    /// The control period, s.
    pub period_s: f64,
    /// The lab's speed limit for this run, mm/s.
    pub speed_limit_mm_s: f64,
}

impl Observation {
    /// The observation as version 1 lays it out.
    pub fn words(&self) -> [f64; OBSERVATION_WORDS] {
        let mut w = [0.0; OBSERVATION_WORDS];
        w[0] = self.t_s;
        w[1] = self.pose.x_mm;
        w[2] = self.pose.y_mm;
        w[3] = self.pose.theta_rad;
        w[4] = self.uncertainty_mm;
        w[5] = self.wheels.left_mm_s;
        w[6] = self.wheels.right_mm_s;
        let goal = self.goal.map_or([f64::NAN; 2], |g| [g.x_mm, g.y_mm]);
        w[7..9].copy_from_slice(&goal);
        w[9..17].copy_from_slice(&self.proximity);
        w[17] = self.period_s;
        w[18] = self.speed_limit_mm_s;
        w
    }

    /// Proximity readings as the observation carries them.
    pub fn proximity_of(readings: &[u16]) -> [f64; 8] {
        let mut out = [0.0; 8];
        for (o, r) in out.iter_mut().zip(readings) {
            *o = f64::from(*r);
        }
        out
    }
}

/// What one step answered.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Answer {
    /// The wheel speeds it asks for, finite (the lab's limits still apply).
    pub wheels: WheelSpeeds,
    /// It says it is done: the run ends.
    pub finished: bool,
}

/// Why a controller was stopped: each ends its run, in these words.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ControllerFault {
    #[error("the controller trapped: {0}")]
    Trapped(String),
    #[error("the controller ran out of fuel: a step may execute {budget} instructions")]
    OutOfFuel { budget: u64 },
    #[error("the controller's step took {took_ms:.1} ms, past its deadline of {deadline_ms:.1} ms")]
    TooSlow { took_ms: f64, deadline_ms: f64 },
    #[error("the controller grew its memory past its cap of {cap_mib} MiB")]
    MemoryCap { cap_mib: usize },
    #[error(
        "the controller asked for wheel speeds that are no finite numbers: {left}, {right} mm/s"
    )]
    NotFinite { left: f64, right: f64 },
    #[error("the controller's vl_init returned {0}, not 0")]
    InitFailed(i32),
}

/// A controller ready to step: a sandboxed module, or anything else that
/// answers observations alike.
pub trait Controller {
    /// One step: `seen` in, wheel speeds out, within the sandbox's bounds.
    fn step(&mut self, seen: &Observation) -> Result<Answer, ControllerFault>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_module_hash_reads_back_as_written() {
        let hash = ModuleHash::of(b"(module)");
        let text = serde_json::to_string(&hash).unwrap();
        assert_eq!(text.len(), 66);
        assert_eq!(serde_json::from_str::<ModuleHash>(&text).unwrap(), hash);
        assert!("xyz".parse::<ModuleHash>().is_err());
        assert!("é".repeat(32).parse::<ModuleHash>().is_err());
    }

    #[test]
    fn the_observation_is_laid_out_as_version_1_says() {
        let seen = Observation {
            t_s: 1.5,
            pose: Pose {
                x_mm: 10.0,
                y_mm: 20.0,
                theta_rad: 0.5,
            },
            uncertainty_mm: 3.0,
            wheels: WheelSpeeds {
                left_mm_s: 4.0,
                right_mm_s: 5.0,
            },
            goal: None,
            proximity: Observation::proximity_of(&[1, 2, 3, 4, 5, 6, 7, 8, 9]),
            period_s: 0.02,
            speed_limit_mm_s: 200.0,
        };
        let w = seen.words();
        assert_eq!(&w[..7], &[1.5, 10.0, 20.0, 0.5, 3.0, 4.0, 5.0]);
        assert!(w[7].is_nan() && w[8].is_nan(), "no goal is NaN");
        assert_eq!(&w[9..17], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        assert_eq!((w[17], w[18]), (0.02, 200.0));
        assert!(w[19..].iter().all(|&x| x == 0.0));
    }
}
