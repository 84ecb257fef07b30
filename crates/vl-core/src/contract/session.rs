//! The session supervisor: the lab's mount → define → execute cycle as a
//! Petri net that runs live. An action is allowed exactly when a transition
//! carrying its label is enabled, so the Host never has to reason about
//! "which messages are valid now" in ad-hoc code.

use thiserror::Error;
use vl_petri::{Marking, Net};

/// What the operator (or the lab itself) asks the session to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    Mount,
    Define,
    Start,
    /// The operator asks the running experiment to stop; `Finish` follows
    /// when the lab has stopped it.
    Stop,
    /// A drive command, during a run.
    Command,
    /// A run ends: stopped by the operator, goal reached, time limit or fault.
    Finish,
    /// The operator leaves; the lab returns to idle from wherever it was.
    Release,
}

impl Action {
    fn label(self) -> &'static str {
        match self {
            Action::Mount => "mount",
            Action::Define => "define",
            Action::Start => "start",
            Action::Stop => "stop",
            Action::Command => "command",
            Action::Finish => "finish",
            Action::Release => "release",
        }
    }
}

/// Which phase of the experiment the lab is in (the marked place).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Idle,
    Mounted,
    Defined,
    Running,
}

const PHASES: [(&str, Phase); 4] = [
    ("idle", Phase::Idle),
    ("mounted", Phase::Mounted),
    ("defined", Phase::Defined),
    ("running", Phase::Running),
];

impl std::fmt::Display for Action {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Action::Mount => "mount an experiment",
            Action::Define => "define the experiment",
            Action::Start => "start a run",
            Action::Stop => "stop a run",
            Action::Command => "drive",
            Action::Finish => "finish a run",
            Action::Release => "release the lab",
        })
    }
}

impl std::fmt::Display for Phase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Phase::Idle => "no experiment is mounted",
            Phase::Mounted => "no run is going",
            Phase::Defined => "no run is going",
            Phase::Running => "a run is going",
        })
    }
}

/// An action the session net does not enable now.
#[derive(Debug, Error, PartialEq, Eq)]
#[error("cannot {action} now: {phase}")]
pub struct NotAllowed {
    pub action: Action,
    pub phase: Phase,
}

/// The live session net and its current marking.
#[derive(Debug, Clone)]
pub struct Supervisor {
    net: Net,
    marking: Marking,
}

impl Default for Supervisor {
    fn default() -> Self {
        Self::new()
    }
}

impl Supervisor {
    /// The lab's session net: one place per phase, one transition per allowed move.
    pub fn new() -> Self {
        let mut net = Net::new("session");
        for (name, phase) in PHASES {
            net.add_place(name, u32::from(phase == Phase::Idle))
                .expect("phase names are distinct");
        }
        let moves: [(&str, Action, &str, &str); 13] = [
            ("mount", Action::Mount, "idle", "mounted"),
            ("remount_mounted", Action::Mount, "mounted", "mounted"),
            ("remount_defined", Action::Mount, "defined", "mounted"),
            ("define", Action::Define, "mounted", "defined"),
            ("redefine", Action::Define, "defined", "defined"),
            ("start", Action::Start, "defined", "running"),
            // Defining is optional: a run may start on the default definition.
            ("start_undefined", Action::Start, "mounted", "running"),
            ("stop", Action::Stop, "running", "running"),
            ("command", Action::Command, "running", "running"),
            ("finish", Action::Finish, "running", "defined"),
            ("release_mounted", Action::Release, "mounted", "idle"),
            ("release_defined", Action::Release, "defined", "idle"),
            ("release_running", Action::Release, "running", "idle"),
        ];
        for (name, action, from, to) in moves {
            net.add_transition_with(name, Some(action.label()), &[(from, 1)], &[(to, 1)])
                .expect("session net arcs name its own places");
        }
        let marking = net.initial_marking();
        Supervisor { net, marking }
    }

    /// The net being run, for analysis and pictures.
    pub fn net(&self) -> &Net {
        &self.net
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        PHASES
            .iter()
            .find(|(name, _)| {
                let place = self.net.place(name).expect("every phase has a place");
                self.marking.tokens(place) > 0
            })
            .map(|&(_, phase)| phase)
            .expect("the session net always marks one phase")
    }

    /// Whether `action` may happen now.
    pub fn allows(&self, action: Action) -> bool {
        self.enabled_for(action).is_some()
    }

    /// Says why `action` may not happen now, if it may not.
    pub fn check(&self, action: Action) -> Result<(), NotAllowed> {
        self.enabled_for(action).map(drop).ok_or(NotAllowed {
            action,
            phase: self.phase(),
        })
    }

    /// Performs `action`, or says why it may not happen now.
    pub fn fire(&mut self, action: Action) -> Result<Phase, NotAllowed> {
        let t = self.enabled_for(action).ok_or(NotAllowed {
            action,
            phase: self.phase(),
        })?;
        self.marking = self
            .net
            .fire(&self.marking, t)
            .expect("an enabled transition fires");
        Ok(self.phase())
    }

    fn enabled_for(&self, action: Action) -> Option<vl_petri::TransitionId> {
        self.net
            .enabled(&self.marking)
            .find(|t| self.net.transitions[t.0].label.as_deref() == Some(action.label()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_say_what_stands_in_the_way() {
        let refused = Supervisor::new().fire(Action::Start).unwrap_err();
        assert_eq!(
            refused.to_string(),
            "cannot start a run now: no experiment is mounted"
        );
    }

    #[test]
    fn the_experiment_cycle() {
        let mut s = Supervisor::new();
        assert_eq!(s.phase(), Phase::Idle);
        assert_eq!(
            s.fire(Action::Start),
            Err(NotAllowed {
                action: Action::Start,
                phase: Phase::Idle
            })
        );
        assert_eq!(s.fire(Action::Mount), Ok(Phase::Mounted));
        assert!(s.allows(Action::Start), "defining is optional");
        assert!(!s.allows(Action::Command), "no commands before a run");
        assert_eq!(s.fire(Action::Define), Ok(Phase::Defined));
        assert!(!s.allows(Action::Stop), "nothing to stop");
        assert_eq!(s.fire(Action::Start), Ok(Phase::Running));
        assert_eq!(s.fire(Action::Command), Ok(Phase::Running));
        assert_eq!(
            s.fire(Action::Stop),
            Ok(Phase::Running),
            "until the lab finishes"
        );
        assert!(!s.allows(Action::Define), "no redefinition mid-run");
        assert!(!s.allows(Action::Mount), "no remount mid-run");
        assert_eq!(s.fire(Action::Finish), Ok(Phase::Defined));
        assert_eq!(s.fire(Action::Start), Ok(Phase::Running));
        assert_eq!(s.fire(Action::Release), Ok(Phase::Idle));
    }
}
