//! The user's own controller beside the control loop (issue 58): a module
//! stepped on a thread of its own every `STEP_PERIOD_S` with the loop's
//! newest observation. The loop never waits on it: it offers an
//! observation when one is due and the last step is done, takes whatever
//! answers have come, and a command older than `STALE` counts as none.

use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread;
use std::time::{Duration, Instant};

use vl_core::{
    Answer, Controller, ControllerFault, Definition, Observation, Pose, RobotModel, STEP_PERIOD_S,
    WheelSpeeds,
};
use vl_record::{Feed, Level, Recordable};
use vl_sandbox::{Budget, Module};

use crate::drivers::RobotReading;

/// A controller's command is followed this long, then the robot stops
/// until the next: three steps, so one late step costs nothing.
pub(super) const STALE: Duration = Duration::from_millis(60);

/// What the controller's thread says after a step.
enum Stepped {
    Answer {
        answer: Answer,
        /// The lines it logged (within its rate), and how many more it tried to.
        logged: Vec<String>,
        dropped: u64,
    },
    Fault(ControllerFault),
}

/// The controller of the run under way, on its thread.
pub(super) struct Beside {
    observations: SyncSender<Observation>,
    answers: Receiver<Stepped>,
    next_step: Instant,
    /// Steps skipped because the last one was not done yet.
    pub(super) late: u64,
}

impl Beside {
    /// Starts `module` for a run on a thread of its own (its `vl_init` too:
    /// nothing of it runs on the control loop).
    pub(super) fn spawn(module: Arc<Module>) -> Beside {
        let (observations, seen) = mpsc::sync_channel::<Observation>(1);
        let (said, answers) = mpsc::sync_channel(4);
        thread::Builder::new()
            .name("vl-controller".into())
            .spawn(move || {
                let mut instance = match module.start(Budget::LAB) {
                    Ok(instance) => instance,
                    Err(e) => {
                        let _ = said.send(Stepped::Fault(e.into()));
                        return;
                    }
                };
                // Until the run ends (the loop drops its sender) or it fails.
                while let Ok(observation) = seen.recv() {
                    let stepped = match instance.step(&observation) {
                        Ok(answer) => {
                            let (logged, dropped) = instance.take_log();
                            Stepped::Answer {
                                answer,
                                logged,
                                dropped,
                            }
                        }
                        Err(fault) => Stepped::Fault(fault),
                    };
                    let failed = matches!(stepped, Stepped::Fault(_));
                    if said.send(stepped).is_err() || failed {
                        return;
                    }
                }
            })
            .expect("the OS starts a thread");
        Beside {
            observations,
            answers,
            next_step: Instant::now(),
            late: 0,
        }
    }

    /// Hands the controller an observation if a step is due; a step still
    /// under way skips this one.
    pub(super) fn offer(&mut self, observe: impl FnOnce() -> Observation) {
        let now = Instant::now();
        if now < self.next_step {
            return;
        }
        self.next_step = now + Duration::from_secs_f64(STEP_PERIOD_S);
        match self.observations.try_send(observe()) {
            Ok(()) | Err(TrySendError::Disconnected(_)) => {}
            Err(TrySendError::Full(_)) => self.late += 1,
        }
    }

    /// What the controller said since last asked, its log lines into the
    /// run's `record`: its newest command, that it is done, or its fault.
    pub(super) fn said(&self, record: &Feed) -> Said {
        let mut said = Said::Nothing;
        for stepped in self.answers.try_iter() {
            match stepped {
                Stepped::Answer {
                    answer,
                    logged,
                    dropped,
                } => {
                    for line in logged {
                        record.send(Recordable::Log(Level::Info, format!("controller: {line}")));
                    }
                    if dropped > 0 {
                        let line = format!(
                            "controller: {dropped} more lines not kept (at most {} a second)",
                            vl_sandbox::LOG_LINES_PER_S
                        );
                        record.send(Recordable::Log(Level::Warning, line));
                    }
                    if answer.finished {
                        return Said::Done;
                    }
                    said = Said::Wheels(answer.wheels);
                }
                Stepped::Fault(fault) => return Said::Fault(fault),
            }
        }
        said
    }
}

/// What a controller's answers since last asked come to.
pub(super) enum Said {
    Nothing,
    /// Its newest command, as it asked (the lab's limits still to apply).
    Wheels(WheelSpeeds),
    /// `vl_step` returned 1: the run ends.
    Done,
    Fault(ControllerFault),
}

/// What a controller is told: the run's time, the estimate `at` (and how
/// unsure it is), the robot's `reading`, the definition's goal and limit.
pub(super) fn observation(
    started: Instant,
    definition: &Definition,
    robot: &RobotModel,
    at: (Pose, f64),
    reading: &RobotReading,
) -> Observation {
    Observation {
        t_s: started.elapsed().as_secs_f64(),
        pose: at.0,
        uncertainty_mm: at.1,
        wheels: reading.wheels,
        goal: definition.goal.map(|g| g.point()),
        proximity: Observation::proximity_of(&reading.proximity),
        period_s: STEP_PERIOD_S,
        speed_limit_mm_s: definition.speed_limit_mm_s(robot),
    }
}
