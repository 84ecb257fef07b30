//! The user's own controller beside the control loop (issue 58): a module
//! stepped on a thread of its own every `STEP_PERIOD_S` with the loop's
//! newest observation. The loop never waits on it: it offers an
//! observation when one is due and the last step is done, takes whatever
//! answers have come, and a command older than `STALE` counts as none.

use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread;
use std::time::{Duration, Instant};

use tracing::warn;
use vl_core::{
    Answer, Controller, ControllerFault, EndReason, Observation, Pose, RobotModel, STEP_PERIOD_S,
};
use vl_record::{Feed, Level, Recordable};
use vl_sandbox::{Budget, LoadError, Module};

use super::run::Run;
use crate::drivers::RobotReading;

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
                let mut instance = match module.start(Budget::LAB) {
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

impl Run {
    /// Offers the run's controller its observation when a step is due
    /// (`at`: the estimate and how unsure it is) and takes what it said:
    /// its command (within the definition's cap), its log (into the run's
    /// record), or the fault (or its being done) that ends the run.
    pub(super) fn tend_controller(
        &mut self,
        robot: &RobotModel,
        at: (Pose, f64),
        reading: &RobotReading,
        record: &Feed,
    ) -> Option<EndReason> {
        let beside = self.controller.as_mut()?;
        let definition = &self.definition;
        let started = self.started;
        beside.offer(|| Observation {
            t_s: started.elapsed().as_secs_f64(),
            pose: at.0,
            uncertainty_mm: at.1,
            wheels: reading.wheels,
            goal: definition.goal.map(|g| g.point()),
            proximity: Observation::proximity_of(&reading.proximity),
            period_s: STEP_PERIOD_S,
            speed_limit_mm_s: definition.speed_limit_mm_s(robot),
        });
        for stepped in beside.said() {
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
                        return Some(EndReason::ControllerDone);
                    }
                    self.wheels = self.definition.capped(robot, answer.wheels);
                    self.commanded = true;
                    self.last_command = Instant::now();
                }
                Stepped::Fault(fault) => {
                    warn!("{fault}: stopping the run");
                    self.fault = Some(fault.to_string());
                    return Some(EndReason::Fault);
                }
            }
        }
        None
    }
}
