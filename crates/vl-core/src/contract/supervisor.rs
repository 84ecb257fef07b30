//! The session supervisor: each experiment's controlled net, as its
//! design gives it from its statecharts (`vl_core::Experiments`), run live. An action is allowed exactly when a transition
//! carrying its event is enabled in the mounted lab's net, so the Host and
//! the Guest never reason about "which messages are valid now" in ad-hoc
//! code, and changing a chart changes what they allow. On the Host the
//! access net runs beside it: an action happens only when both enable it.

use std::path::Path;

use serde::{Deserialize, Serialize};
use thiserror::Error;
use vl_petri::{Marking, Net, TransitionId, from_pnml};

use super::access::{AccessEvent, AccessNet, AccessRefused, Seat};
use crate::ExperimentId;

/// What the operator or the lab does: each is an event of the labs' nets.
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
    /// The Host has grown the mounted map into the robot's C-space.
    CspaceBuilt,
    /// The Host has checked (or planned) the defined path in its C-space.
    PathPlanned,
    /// The definition's forecast passed the lab's limits, or did not.
    ForecastPassed,
    ForecastFailed,
    /// The Host has built the map's potential field for assisted driving.
    FieldBuilt,
}

impl Action {
    /// The event its transitions carry in the nets.
    pub fn event(self) -> &'static str {
        match self {
            Action::Mount => "mount",
            Action::Define => "define",
            Action::Start => "start",
            Action::Stop => "stop",
            Action::Command => "command",
            Action::Finish => "finish",
            Action::Release => "release",
            Action::CspaceBuilt => "cspace_built",
            Action::PathPlanned => "path_planned",
            Action::ForecastPassed => "forecast_passed",
            Action::ForecastFailed => "forecast_failed",
            Action::FieldBuilt => "field_built",
        }
    }
}

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
            Action::CspaceBuilt => "finish the C-space",
            Action::PathPlanned => "finish the path",
            Action::ForecastPassed => "pass the forecast",
            Action::ForecastFailed => "refuse the forecast",
            Action::FieldBuilt => "finish the potential field",
        })
    }
}

/// An action the net does not enable now: which event, in which lab's
/// net, at which marking.
#[derive(Debug, Error, PartialEq, Eq)]
#[error(
    "cannot {action} now: no `{event}` transition of the {lab} net is enabled at marking {{{}}}",
    marking.join(", ")
)]
pub struct NotAllowed {
    pub action: Action,
    pub event: &'static str,
    pub lab: String,
    /// The marked places, by id.
    pub marking: Vec<String>,
}

#[derive(Debug, Error)]
pub enum SupervisorError {
    #[error("{lab}: cannot read {path}: {why}")]
    Read {
        lab: ExperimentId,
        path: String,
        why: String,
    },
    #[error("{lab}: {why}")]
    Net { lab: ExperimentId, why: String },
    #[error("no lab to supervise")]
    NoLab,
    #[error(transparent)]
    Access(#[from] super::access::AccessNetError),
}

/// What the supervisor did or is: the mounted lab, its marked places and
/// enabled events, and the transitions fired since the last state told.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema)]
pub struct NetState {
    /// The lab whose net runs; none before the first mount.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lab: Option<ExperimentId>,
    /// Marked places, by id (every place of these nets holds one token at most).
    pub marking: Vec<String>,
    /// Events with an enabled transition.
    pub enabled: Vec<String>,
    /// Transitions fired since the last state, in order; each lab's net
    /// starts from its initial marking. Firings that leave the marking as
    /// it was (a command during a run) are not listed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fired: Vec<Fired>,
}

/// A transition fired in a lab's net.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Fired {
    pub lab: ExperimentId,
    /// The transition's id.
    pub transition: String,
}

/// One lab's net and its marking.
#[derive(Debug, Clone)]
struct LabNet {
    lab: ExperimentId,
    net: Net,
    marking: Marking,
}

/// The live nets of the labs a Host offers, and which one is mounted.
#[derive(Debug, Clone)]
pub struct Supervisor {
    labs: Vec<LabNet>,
    mounted: Option<usize>,
    /// Who may drive, on the Host; a Guest follows the lab's nets only.
    access: Option<AccessNet>,
    /// Fired since [`Supervisor::take_state`] last said.
    fired: Vec<Fired>,
}

impl Supervisor {
    /// A supervisor of each experiment's controlled net, as its design
    /// gives it (`Experiments::nets`).
    pub fn new(nets: Vec<(ExperimentId, Net)>) -> Result<Supervisor, SupervisorError> {
        Supervisor::from_nets(nets)
    }

    /// The nets of `labs` from `dir/<lab>/controlled.pnml`, as `vl lab nets
    /// --out dir` writes them.
    pub fn load(dir: &Path, labs: &[ExperimentId]) -> Result<Supervisor, SupervisorError> {
        let nets = labs
            .iter()
            .map(|lab| {
                let path = dir.join(lab.as_str()).join("controlled.pnml");
                let text = std::fs::read_to_string(&path).map_err(|e| SupervisorError::Read {
                    lab: lab.clone(),
                    path: path.display().to_string(),
                    why: e.to_string(),
                })?;
                let net = from_pnml(&text).map_err(|e| SupervisorError::Net {
                    lab: lab.clone(),
                    why: e.to_string(),
                })?;
                Ok((lab.clone(), net))
            })
            .collect::<Result<Vec<_>, SupervisorError>>()?;
        Supervisor::from_nets(nets)
    }

    fn from_nets(nets: Vec<(ExperimentId, Net)>) -> Result<Supervisor, SupervisorError> {
        if nets.is_empty() {
            return Err(SupervisorError::NoLab);
        }
        Ok(Supervisor {
            labs: nets
                .into_iter()
                .map(|(lab, net)| LabNet {
                    lab,
                    marking: net.initial_marking(),
                    net,
                })
                .collect(),
            mounted: None,
            access: None,
            fired: Vec::new(),
        })
    }

    /// This supervisor with `access` run beside the labs' nets.
    pub fn with_access(mut self, access: AccessNet) -> Supervisor {
        self.access = Some(access);
        self
    }

    /// Fires one person's access events, all or none (see
    /// [`AccessNet::fire_all`]); without an access net, everything is allowed.
    pub fn access(&mut self, steps: &[(AccessEvent, Seat)]) -> Result<(), AccessRefused> {
        match &mut self.access {
            Some(access) => access.fire_all(steps),
            None => Ok(()),
        }
    }

    /// How many people are at `seat` in the access net.
    pub fn seated(&self, seat: Seat) -> Option<u32> {
        self.access.as_ref().map(|a| a.at(seat))
    }

    /// The net that answers now: the mounted lab's, or before any mount
    /// the first lab's (every lab's net starts unmounted).
    fn current(&self) -> &LabNet {
        &self.labs[self.mounted.unwrap_or(0)]
    }

    /// The mounted lab.
    pub fn lab(&self) -> Option<&ExperimentId> {
        self.mounted.map(|i| &self.labs[i].lab)
    }

    /// Whether it runs the net of experiment `lab`.
    pub fn runs(&self, lab: &ExperimentId) -> bool {
        self.labs.iter().any(|l| l.lab == *lab)
    }

    /// The current net and its marking.
    pub fn marked(&self) -> (&Net, &Marking) {
        let l = self.current();
        (&l.net, &l.marking)
    }

    /// Whether `action` may happen now.
    pub fn allows(&self, action: Action) -> bool {
        self.check(action).is_ok()
    }

    /// Says why `action` may not happen now, if it may not.
    pub fn check(&self, action: Action) -> Result<(), NotAllowed> {
        self.enabled(action).map(drop)
    }

    /// The transitions `action` fires now: in the current lab's net, and
    /// in the access net where it carries the event; or why it may not.
    fn enabled(&self, action: Action) -> Result<(TransitionId, Option<TransitionId>), NotAllowed> {
        let lab = enabled_for(self.current(), action).ok_or_else(|| self.refusal(action))?;
        let Some(access) = &self.access else {
            return Ok((lab, None));
        };
        let access_t = access.carrying(action.event()).map_err(|()| NotAllowed {
            action,
            event: action.event(),
            lab: "access".to_owned(),
            marking: access.marked(),
        })?;
        Ok((lab, access_t))
    }

    /// Fires `action`'s transition, or says why it may not happen now. A
    /// release leaves no lab mounted.
    pub fn fire(&mut self, action: Action) -> Result<(), NotAllowed> {
        let (lab, access_t) = self.enabled(action)?;
        let i = self.mounted.unwrap_or(0);
        fire_at(&mut self.labs[i], lab, &mut self.fired);
        if let (Some(access), Some(t)) = (&mut self.access, access_t) {
            access.fire_at(t);
        }
        if action == Action::Release {
            self.mounted = None;
        }
        Ok(())
    }

    /// Mounts `lab`: in its net if it is mounted already, else releasing
    /// the one mounted (if its net allows mounting now) and mounting in
    /// `lab`'s.
    pub fn mount(&mut self, lab: &ExperimentId) -> Result<(), NotAllowed> {
        self.check(Action::Mount)?;
        let Some(to) = self.labs.iter().position(|l| l.lab == *lab) else {
            return Err(self.refusal(Action::Mount));
        };
        if let Some(from) = self.mounted.filter(|&from| from != to) {
            let release = enabled_for(&self.labs[from], Action::Release)
                .ok_or_else(|| self.refusal(Action::Release))?;
            fire_at(&mut self.labs[from], release, &mut self.fired);
        }
        self.mounted = Some(to);
        self.fire(Action::Mount)
    }

    /// The state now, with the transitions fired since it was last
    /// taken; none if nothing was.
    pub fn take_state(&mut self) -> Option<NetState> {
        if self.fired.is_empty() {
            return None;
        }
        let fired = std::mem::take(&mut self.fired);
        Some(NetState {
            fired,
            ..self.state()
        })
    }

    /// The state now, without what was fired.
    pub fn state(&self) -> NetState {
        let l = self.current();
        let mut enabled: Vec<String> = l
            .net
            .enabled(&l.marking)
            .filter_map(|t| l.net.transitions[t.0].label.clone())
            .collect();
        enabled.sort();
        enabled.dedup();
        NetState {
            lab: self.lab().cloned(),
            marking: marked(l),
            enabled,
            fired: Vec::new(),
        }
    }

    /// Follows what another supervisor fired (a Guest following its
    /// Host's): mounts `state.lab` when it changes, fires each of
    /// `state.fired` by id, and says whether the marking it reaches is the
    /// one `state` tells. On a difference (a transition not enabled here, a
    /// marking apart) it takes the told marking, so it stays in step; a
    /// state that fired nothing (a welcome) is taken as it is.
    pub fn follow(&mut self, state: &NetState) -> bool {
        let mut agrees = true;
        if state.fired.is_empty() {
            for l in &mut self.labs {
                l.marking = l.net.initial_marking();
            }
        }
        for fired in &state.fired {
            let Some((l, t)) = self.labs.iter_mut().find_map(|l| {
                let t = l
                    .net
                    .transition(&fired.transition)
                    .filter(|_| l.lab == fired.lab)?;
                Some((l, t))
            }) else {
                agrees = false;
                continue;
            };
            match l.net.fire(&l.marking, t) {
                Ok(m) if l.net.is_enabled(&l.marking, t) => l.marking = m,
                _ => agrees = false,
            }
        }
        self.mounted = state
            .lab
            .as_ref()
            .and_then(|lab| self.labs.iter().position(|l| l.lab == *lab));
        let i = self.mounted.unwrap_or(0);
        let l = &mut self.labs[i];
        if marked(l) != state.marking {
            agrees &= state.fired.is_empty();
            l.marking = Marking(
                l.net
                    .places
                    .iter()
                    .map(|p| u32::from(state.marking.contains(&p.id)))
                    .collect(),
            );
        }
        agrees
    }

    fn refusal(&self, action: Action) -> NotAllowed {
        let l = self.current();
        NotAllowed {
            action,
            event: action.event(),
            lab: l.lab.to_string(),
            marking: marked(l),
        }
    }
}

fn marked(l: &LabNet) -> Vec<String> {
    l.marking
        .0
        .iter()
        .zip(&l.net.places)
        .filter(|(n, _)| **n > 0)
        .map(|(_, p)| p.id.clone())
        .collect()
}

fn enabled_for(l: &LabNet, action: Action) -> Option<TransitionId> {
    l.net
        .enabled(&l.marking)
        .find(|t| l.net.transitions[t.0].label.as_deref() == Some(action.event()))
}

/// Fires `l`'s enabled transition `t`, noting it in `fired` when it changed the marking.
fn fire_at(l: &mut LabNet, t: TransitionId, fired: &mut Vec<Fired>) {
    let after = l
        .net
        .fire(&l.marking, t)
        .expect("an enabled transition fires");
    let before = std::mem::replace(&mut l.marking, after);
    if before != l.marking {
        fired.push(Fired {
            lab: l.lab.clone(),
            transition: l.net.transitions[t.0].id.clone(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn both() -> Supervisor {
        Supervisor::new(crate::Experiments::shipped().nets()).unwrap()
    }

    fn id(id: &str) -> ExperimentId {
        ExperimentId::new(id).unwrap()
    }

    #[test]
    fn refusals_name_the_event_and_the_marking() {
        let refused = both().fire(Action::Start).unwrap_err();
        let text = refused.to_string();
        assert!(
            text.starts_with("cannot start a run now: no `start` transition of the navigation net is enabled at marking {mount.idle"),
            "{text}"
        );
    }

    #[test]
    fn the_navigation_cycle() {
        let mut s = both();
        assert!(!s.allows(Action::Define), "nothing mounted");
        s.mount(&id("navigation")).unwrap();
        assert!(!s.allows(Action::Define), "the C-space is being built");
        assert!(!s.allows(Action::Start), "the C-space is being built");
        s.fire(Action::CspaceBuilt).unwrap();
        assert!(!s.allows(Action::Start), "nothing tried on the twin yet");
        assert!(!s.allows(Action::Command), "no commands before a run");
        s.fire(Action::Define).unwrap();
        assert!(!s.allows(Action::Start), "the path is being checked");
        s.fire(Action::PathPlanned).unwrap();
        assert!(!s.allows(Action::Start), "the forecast is under way");
        s.fire(Action::ForecastFailed).unwrap();
        assert!(!s.allows(Action::Start), "the forecast was refused");
        s.fire(Action::Define).unwrap();
        s.fire(Action::PathPlanned).unwrap();
        s.fire(Action::ForecastPassed).unwrap();
        assert!(!s.allows(Action::Stop), "nothing to stop");
        s.fire(Action::Start).unwrap();
        s.fire(Action::Command).unwrap();
        assert!(!s.allows(Action::Define), "no redefinition mid-run");
        assert!(!s.allows(Action::Mount), "no remount mid-run");
        s.fire(Action::Stop).unwrap();
        assert!(!s.allows(Action::Command), "stopping");
        s.fire(Action::Finish).unwrap();
        assert!(!s.allows(Action::Start), "the next run starts elsewhere");
        s.fire(Action::ForecastPassed).unwrap();
        s.fire(Action::Start).unwrap();
        s.fire(Action::Release).unwrap();
        assert_eq!(s.state().marking, {
            let fresh = both();
            fresh.state().marking
        });
    }

    #[test]
    fn mounting_another_lab_releases_the_first_and_a_follower_keeps_step() {
        let mut host = both();
        let mut guest = both();
        host.mount(&id("navigation")).unwrap();
        host.fire(Action::CspaceBuilt).unwrap();
        assert!(guest.follow(&host.take_state().unwrap()));
        host.mount(&id("teleoperation")).unwrap();
        assert_eq!(host.lab(), Some(&id("teleoperation")));
        assert!(!host.allows(Action::Start), "no field yet");
        host.fire(Action::CspaceBuilt).unwrap();
        host.fire(Action::FieldBuilt).unwrap();
        assert!(host.allows(Action::Start));
        let state = host.take_state().unwrap();
        assert!(guest.follow(&state), "{state:?}");
        assert_eq!(guest.state().marking, host.state().marking);
        assert!(guest.allows(Action::Start));
    }
}
