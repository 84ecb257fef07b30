//! What the Guest may do now and what it should do next: the mounted
//! experiment's net (run here, or as the Host tells it), the lab's
//! readiness, and the next step in words.

use vl_core::{Action, Experiment, Readiness};

use super::Session;

impl Session {
    /// Whether this Guest may ask for `action` now: it is the operator and
    /// the lab's net, run here from the Host's firings, enables it; a run
    /// (and its definition, planned from where the robot stands) waits
    /// while the lab gets ready.
    pub fn allows(&self, action: Action) -> bool {
        let waits = matches!(action, Action::Start | Action::Define) && !self.ready();
        self.is_operator() && self.net_allows(action) && !waits
    }

    /// Whether the mounted experiment's net enables `action` now: the net
    /// run here, or, for an experiment whose net this Guest does not have,
    /// the events the Host last told enabled.
    pub fn net_allows(&self, action: Action) -> bool {
        match self.told.as_ref().filter(|t| !self.has_net(t.lab.as_ref())) {
            Some(told) => told.enabled.iter().any(|e| e == action.event()),
            None => self.nets.allows(action),
        }
    }

    /// Whether this Guest runs the net of the experiment `lab` (none:
    /// nothing mounted, every net's start is the same).
    pub fn has_net(&self, lab: Option<&vl_core::ExperimentId>) -> bool {
        lab.is_none_or(|lab| self.nets.runs(lab))
    }

    /// Whether the lab is ready for a run, as the Host last said.
    pub fn ready(&self) -> bool {
        self.devices.is_none_or(|d| d.lab == Readiness::Ready)
    }

    /// What the operator may do next, in words (a lab's state names its
    /// next action); none for someone watching, whose place in line says it.
    pub fn next_step(&self) -> Option<&'static str> {
        if !self.is_operator() {
            return None;
        }
        if self.lab.is_none() {
            return Some("Next: mount an experiment.");
        }
        let navigation = self.mounted().is_some_and(Experiment::follows);
        let controls = self.mounted().is_some_and(Experiment::runs_a_controller);
        if self.running {
            return Some(if controls {
                "Your controller drives: Stop ends the run, STOP halts the robot at once."
            } else if navigation {
                "Running: Stop ends the run, STOP halts the robot at once."
            } else {
                "Drive with the stick or the arrow keys: Stop ends the run, STOP halts it at once."
            });
        }
        if !self.ready() {
            return Some("Wait: the robot drives back to its start.");
        }
        let visits = self
            .mounted()
            .and_then(Experiment::waypoint_bounds)
            .is_some();
        let Some(definition) = &self.definition else {
            return Some(if controls && self.controller.is_none() {
                "Next: send your controller: Choose… its file, or drop it on the window."
            } else if controls {
                "Next: click the view for its goal, then Define."
            } else if visits {
                "Next: click the view for each point to visit, in order, then Define."
            } else if navigation {
                "Next: click the view for a goal, then Define."
            } else {
                "Next: Define the run (no path: you drive), then Start."
            });
        };
        match &self.forecast {
            None if definition.path.len() > 1 || controls => {
                Some("The lab's twin tries the definition first…")
            }
            Some(f) if !f.passed() && controls => {
                Some("Next: change your controller or its goal: the twin refused it.")
            }
            Some(f) if !f.passed() => {
                Some("Next: another goal or path: the twin refused this one.")
            }
            _ if self.allows(Action::Start) => Some("Next: Start the run."),
            _ => None,
        }
    }
}
