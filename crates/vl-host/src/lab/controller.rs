//! The user's own controller beside the control loop (issue 58): a module
//! stepped on a thread of its own every `STEP_PERIOD_S` with the loop's
//! newest observation. The loop never waits on it: it offers an
//! observation when one is due and the last step is done, takes whatever
//! answers have come, and a command older than `STALE` counts as none.

use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread;
use std::time::{Duration, Instant};

use vl_core::{Answer, Controller, ControllerFault, Observation, STEP_PERIOD_S};
use vl_sandbox::{Limits, LoadError, Module};

/// A controller's command is followed this long, then the robot stops
/// until the next: three steps, so one late step costs nothing.
pub(super) const STALE: Duration = Duration::from_millis(60);

/// What the controller's thread says after a step.
pub(super) enum Stepped {
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
                let mut instance = match module.start(Limits::LAB) {
                    Ok(instance) => instance,
                    Err(LoadError::Start(fault)) => {
                        let _ = said.send(Stepped::Fault(fault));
                        return;
                    }
                    Err(other) => {
                        let _ =
                            said.send(Stepped::Fault(ControllerFault::Trapped(other.to_string())));
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

    /// What the controller said since last asked.
    pub(super) fn said(&self) -> Vec<Stepped> {
        self.answers.try_iter().collect()
    }
}
