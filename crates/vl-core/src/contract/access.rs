//! Who drives, run as a net: the access design's controlled net (`vl lab
//! nets` writes it to `crates/vl-core/nets/access/`, built in), live beside the
//! mounted lab's. Each person is a token in the access chart's places; the
//! Host fires the chart's events as people ask, wait, drive and go, and an
//! event the net does not enable does not happen — so a second operator,
//! a grant past the head of the line, a run with no operator, or a slot
//! that ends with the robot still running are unreachable by construction,
//! not by the hub's bookkeeping. The lab's own events (start, release…)
//! fire here too where the net has them: that is the composition.

use std::fmt;
use std::path::Path;

use thiserror::Error;
use vl_petri::{Marking, Net, TransitionId, from_pnml};

/// The access design's folder, in `crates/vl-core/nets/` and `vl lab nets --out`.
const FOLDER: &str = "access";

/// The access design's controlled net, as `vl lab nets` wrote it.
const SHIPPED: &str = include_str!("../../nets/access/controlled.pnml");

/// People the live net has room for: the design is checked with a few,
/// and its rules hold for any number; the Host lets in far fewer.
const PEOPLE: u32 = 1 << 16;

/// Where a person stands: the access chart's states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seat {
    Observer,
    /// In line, behind its head.
    Waiting,
    /// First in line: the next to be granted control.
    Head,
    Operator,
}

impl Seat {
    fn place(self) -> &'static str {
        match self {
            Seat::Observer => "access.observer",
            Seat::Waiting => "access.waiting",
            Seat::Head => "access.head",
            Seat::Operator => "access.operator",
        }
    }
}

impl fmt::Display for Seat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Seat::Observer => "watching",
            Seat::Waiting => "waiting in line",
            Seat::Head => "at the head of the line",
            Seat::Operator => "driving",
        })
    }
}

/// What happens to a person's access: the access chart's events.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccessEvent {
    /// An observer asks for control and joins the line.
    Ask,
    /// The next in line moves up to its empty head.
    Advance,
    /// Control is given.
    Grant,
    /// Someone in line gives up their place (or it lapses).
    LeaveQueue,
    /// The operator's slot is over.
    SlotEnd,
    /// The operator leaves, drops past the grace, or goes silent.
    Leave,
    /// An administrator ends someone's turn or place.
    Kick,
}

impl fmt::Display for AccessEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.event())
    }
}

impl AccessEvent {
    /// The event its transitions carry in the net.
    fn event(self) -> &'static str {
        match self {
            AccessEvent::Ask => "ask",
            AccessEvent::Advance => "advance",
            AccessEvent::Grant => "grant",
            AccessEvent::LeaveQueue => "leave_queue",
            AccessEvent::SlotEnd => "slot_end",
            AccessEvent::Leave => "leave",
            AccessEvent::Kick => "kick",
        }
    }
}

/// An access net that cannot run.
#[derive(Debug, Error)]
pub enum AccessNetError {
    #[error("access: cannot read {path}: {why}")]
    Read { path: String, why: String },
    #[error("access: {0}")]
    Net(String),
}

/// An access event the net does not enable now.
#[derive(Debug, Error, PartialEq, Eq)]
#[error(
    "the access net does not let someone {seat} {event} now: no `{event}` transition out of \
     `{}` is enabled at marking {{{}}}",
    seat.place(),
    marking.join(", ")
)]
pub struct AccessRefused {
    pub event: &'static str,
    pub seat: Seat,
    /// The marked places, by id, with their tokens when more than one.
    pub marking: Vec<String>,
}

/// The access design's controlled net and its marking.
#[derive(Debug, Clone)]
pub struct AccessNet {
    net: Net,
    marking: Marking,
}

impl AccessNet {
    /// The shipped net.
    pub fn new() -> Result<AccessNet, AccessNetError> {
        AccessNet::parse(SHIPPED)
    }

    /// The net from `dir/access/controlled.pnml`, as `vl lab nets --out
    /// dir` writes it.
    pub fn load(dir: &Path) -> Result<AccessNet, AccessNetError> {
        let path = dir.join(FOLDER).join("controlled.pnml");
        let text = std::fs::read_to_string(&path).map_err(|e| AccessNetError::Read {
            path: path.display().to_string(),
            why: e.to_string(),
        })?;
        AccessNet::parse(&text)
    }

    fn parse(text: &str) -> Result<AccessNet, AccessNetError> {
        let mut net = from_pnml(text).map_err(|e| AccessNetError::Net(e.to_string()))?;
        let everyone = net.place(Seat::Observer.place()).ok_or_else(|| {
            AccessNetError::Net(format!("the net has no place `{}`", Seat::Observer.place()))
        })?;
        net.places[everyone.0].initial = PEOPLE;
        Ok(AccessNet {
            marking: net.initial_marking(),
            net,
        })
    }

    /// Fires each `(event, seat)` in turn, all or none: one person's steps
    /// (ask, move up, be granted) happen together or not at all.
    pub fn fire_all(&mut self, steps: &[(AccessEvent, Seat)]) -> Result<(), AccessRefused> {
        let before = self.marking.clone();
        for &(event, seat) in steps {
            if let Err(refused) = self.fire(event, seat) {
                self.marking = before;
                return Err(refused);
            }
        }
        Ok(())
    }

    /// Fires `event` for someone at `seat`, or says why it may not happen.
    pub fn fire(&mut self, event: AccessEvent, seat: Seat) -> Result<(), AccessRefused> {
        let from = self.net.place(seat.place());
        let out_of_seat = |t: &TransitionId| {
            from.is_some_and(|p| self.net.transitions[t.0].pre.iter().any(|a| a.place == p))
        };
        let Some(t) = self.enabled(event.event()).find(out_of_seat) else {
            return Err(AccessRefused {
                event: event.event(),
                seat,
                marking: self.marked(),
            });
        };
        self.fire_at(t);
        Ok(())
    }

    /// How many people are at `seat`.
    pub fn at(&self, seat: Seat) -> u32 {
        self.net
            .place(seat.place())
            .map_or(0, |p| self.marking.tokens(p))
    }

    /// The transition the lab's `event` fires here: none when the net
    /// carries no such event (not its concern), an error when it carries
    /// it but none is enabled.
    pub(crate) fn carrying(&self, event: &str) -> Result<Option<TransitionId>, ()> {
        let carried = self
            .net
            .transitions
            .iter()
            .any(|t| t.label.as_deref() == Some(event));
        match self.enabled(event).next() {
            Some(t) => Ok(Some(t)),
            None if carried => Err(()),
            None => Ok(None),
        }
    }

    /// Fires transition `t`, which [`AccessNet::carrying`] found enabled.
    pub(crate) fn fire_at(&mut self, t: TransitionId) {
        self.marking = self
            .net
            .fire(&self.marking, t)
            .expect("an enabled transition fires");
    }

    fn enabled<'a>(&'a self, event: &'a str) -> impl Iterator<Item = TransitionId> + 'a {
        self.net
            .enabled(&self.marking)
            .filter(move |t| self.net.transitions[t.0].label.as_deref() == Some(event))
    }

    /// The marked places, as `access.head` or `access.observer×65535`.
    pub fn marked(&self) -> Vec<String> {
        self.marking
            .0
            .iter()
            .zip(&self.net.places)
            .filter(|(n, _)| **n > 0)
            .map(|(&n, p)| match n {
                1 => p.id.clone(),
                n => format!("{}×{n}", p.id),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl AccessNet {
        /// Fires the lab's `event`, which must be enabled.
        fn take(&mut self, event: &str) {
            let t = self.carrying(event).unwrap().expect("carried");
            self.fire_at(t);
        }
    }

    #[test]
    fn the_line_is_fair_and_the_operator_one() {
        let mut a = AccessNet::new().unwrap();
        a.fire(AccessEvent::Ask, Seat::Observer).unwrap();
        let before = a.marked();
        let refused = a.fire_all(&[
            (AccessEvent::Ask, Seat::Observer),
            (AccessEvent::Grant, Seat::Waiting),
        ]);
        assert!(refused.is_err(), "a grant to someone not at the head");
        assert_eq!(a.marked(), before, "all or none");
        a.fire(AccessEvent::Ask, Seat::Observer).unwrap();
        let past_the_head = a.fire(AccessEvent::Grant, Seat::Waiting).unwrap_err();
        assert!(
            past_the_head
                .to_string()
                .contains("out of `access.waiting`"),
            "{past_the_head}"
        );
        a.fire(AccessEvent::Advance, Seat::Waiting).unwrap();
        assert!(
            a.fire(AccessEvent::Advance, Seat::Waiting).is_err(),
            "one head"
        );
        a.fire(AccessEvent::Grant, Seat::Head).unwrap();
        a.fire(AccessEvent::Advance, Seat::Waiting).unwrap();
        assert!(
            a.fire(AccessEvent::Grant, Seat::Head).is_err(),
            "one operator"
        );
        assert_eq!((a.at(Seat::Operator), a.at(Seat::Head)), (1, 1));
        assert!(a.carrying("start").is_ok(), "the operator may run");
        a.take("mount");
        a.take("start");
        assert!(
            a.fire(AccessEvent::SlotEnd, Seat::Operator).is_err(),
            "a run under way is stopped first"
        );
        a.take("release");
        a.fire(AccessEvent::SlotEnd, Seat::Operator).unwrap();
        assert!(a.carrying("start").is_err(), "no run without an operator");
        assert!(
            a.carrying("emergency_stop").is_ok(),
            "events it has not are not its concern"
        );
    }
}
