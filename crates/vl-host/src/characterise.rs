//! Speed controller characterisation (thesis C.2) on a Khepera through its
//! serial driver: steps of the speed command, the wheels' speeds sampled as
//! fast as the line allows, and the response law fitted to them. The robot
//! drives back and forth along its heading, at most about 100 mm from
//! where it stands: give it that room.

use std::time::{Duration, Instant};

use thiserror::Error;
use vl_core::{Fit, FitError, ResponseStep, WheelSpeeds, fit_response};

use crate::drivers::{Robot, RobotError};
use crate::khepera::KheperaSerial;

/// Small steps, pulses per 10 ms: within the acceleration limit, so they
/// show the time constant and the dead time. Several sizes, so that the
/// rounding of the readings to whole pulses does not bend every step alike.
const SMALL_PULSES: [i64; 3] = [11, 14, 17];
/// Large steps: beyond it, so they show the limit.
const LARGE_PULSES: i64 = 60;
const SMALL_HOLD: Duration = Duration::from_millis(300);
const LARGE_HOLD: Duration = Duration::from_millis(200);
/// Readings are averaged over windows this long.
const BIN: Duration = Duration::from_millis(1);
/// Each pattern of steps is run this many times.
const REPETITIONS: u32 = 2;

#[derive(Debug, Error)]
pub enum CharacteriseError {
    #[error(transparent)]
    Robot(#[from] RobotError),
    #[error("cannot fit the response: {0}")]
    Fit(#[from] FitError),
}

/// Runs the steps on `robot` and fits its response; `progress` hears what
/// is being done.
pub fn characterise(
    robot: &mut KheperaSerial,
    progress: &mut dyn FnMut(&str),
) -> Result<Fit, CharacteriseError> {
    let per_pulse = robot.model().speed_mm_s(1);
    let mut settled = 0.0;
    let (mut small, mut large) = (Vec::new(), Vec::new());
    let result = (|| {
        for round in 1..=REPETITIONS {
            progress(&format!("round {round} of {REPETITIONS}: small steps"));
            for size in SMALL_PULSES {
                for pulses in [size, 0, -size, 0] {
                    let step = record(robot, settled, pulses as f64 * per_pulse, SMALL_HOLD)?;
                    settled = step.samples.last().map_or(settled, |s| s.1);
                    small.push(step);
                }
            }
            progress(&format!("round {round} of {REPETITIONS}: large steps"));
            for pulses in [LARGE_PULSES, 0, -LARGE_PULSES, 0] {
                let step = record(robot, settled, pulses as f64 * per_pulse, LARGE_HOLD)?;
                settled = step.samples.last().map_or(settled, |s| s.1);
                // Only steps from rest show the limit on their own.
                if pulses != 0 {
                    large.push(step);
                }
            }
        }
        Ok::<(), RobotError>(())
    })();
    // Whatever happened, the wheels are told to stop.
    let stopped = robot.set_speed(WheelSpeeds::default());
    result?;
    stopped?;
    progress("fitting");
    Ok(fit_response(&small, &large)?)
}

/// Commands `to_mm_s` on both wheels and samples their mean speed for `hold`.
fn record(
    robot: &mut KheperaSerial,
    from_mm_s: f64,
    to_mm_s: f64,
    hold: Duration,
) -> Result<ResponseStep, RobotError> {
    let started = Instant::now();
    robot.set_speed(WheelSpeeds {
        left_mm_s: to_mm_s,
        right_mm_s: to_mm_s,
    })?;
    let mut samples = Vec::new();
    while started.elapsed() < hold {
        let asked = started.elapsed();
        let w = robot.wheel_speeds()?;
        // The reading is of some moment during the exchange: its middle.
        let at = (asked + started.elapsed()).as_secs_f64() / 2.0;
        samples.push((at, (w.left_mm_s + w.right_mm_s) / 2.0));
    }
    Ok(ResponseStep {
        from_mm_s,
        to_mm_s,
        samples: binned(&samples),
    })
}

/// Samples averaged over each [`BIN`]: a pseudo-terminal answers in tens
/// of microseconds, far finer than the 10 ms the controller works in.
fn binned(samples: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut bins: Vec<(f64, f64, u32)> = Vec::new();
    for &(t, v) in samples {
        let bin = (t / BIN.as_secs_f64()).floor();
        match bins.last_mut() {
            Some(last) if (last.0 / f64::from(last.2) / BIN.as_secs_f64()).floor() == bin => {
                last.0 += t;
                last.1 += v;
                last.2 += 1;
            }
            _ => bins.push((t, v, 1)),
        }
    }
    bins.into_iter()
        .map(|(t, v, n)| (t / f64::from(n), v / f64::from(n)))
        .collect()
}
