//! Place/transition nets with arc weights, inhibitor arcs, place
//! capacities and transition labels, and their firing rule.
//!
//! A net is kept as per-transition arc lists because the firing rule only
//! ever asks "what does t take, what does t give, what inhibits t".

use std::fmt;

use thiserror::Error;

/// Index of a place in its net.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PlaceId(pub usize);

/// Index of a transition in its net.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TransitionId(pub usize);

/// Tokens per place, indexed by [`PlaceId`].
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Marking(pub Vec<u32>);

impl Marking {
    /// Tokens in `p`.
    pub fn tokens(&self, p: PlaceId) -> u32 {
        self.0[p.0]
    }
}

/// A weighted arc between a place and a transition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arc {
    pub place: PlaceId,
    pub weight: u32,
}

/// A place: its id (unique, used in files and constraints) and its name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Place {
    pub id: String,
    pub name: String,
    pub initial: u32,
    /// At most this many tokens; a transition that would exceed it is disabled.
    pub capacity: Option<u32>,
}

/// A transition: its id and name, the event label it synchronises on, and its arcs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transition {
    pub id: String,
    pub name: String,
    /// The event this transition stands for; transitions of different nets
    /// with the same label fire together when nets are composed.
    pub label: Option<String>,
    /// Input arcs: tokens taken when it fires.
    pub pre: Vec<Arc>,
    /// Output arcs: tokens given when it fires.
    pub post: Vec<Arc>,
    /// Inhibitor arcs: enabled only while the place holds fewer than the weight.
    pub inhibit: Vec<Arc>,
}

/// A place/transition net with its initial marking.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Net {
    pub id: String,
    pub places: Vec<Place>,
    pub transitions: Vec<Transition>,
}

/// Which way an arc runs, as files and builders name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ArcKind {
    /// Place → transition.
    Input,
    /// Transition → place.
    Output,
    /// Place ⊸ transition.
    Inhibitor,
}

/// Why a net could not be built or a transition could not fire.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum NetError {
    #[error("place '{0}' is defined twice")]
    DuplicatePlace(String),
    #[error("transition '{0}' is defined twice")]
    DuplicateTransition(String),
    #[error("an arc of transition '{transition}' names unknown place '{place}'")]
    UnknownPlace { transition: String, place: String },
    #[error("unknown transition '{0}'")]
    UnknownTransition(String),
    #[error("arc between '{place}' and '{transition}' has weight 0")]
    ZeroWeight { transition: String, place: String },
    #[error("transition '{0}' is not enabled")]
    NotEnabled(String),
    #[error("firing '{0}' would overflow a place's token count")]
    Overflow(String),
}

impl Transition {
    /// Every arc of the transition with its kind: inputs, outputs, inhibitors.
    pub fn arcs(&self) -> impl Iterator<Item = (ArcKind, &Arc)> {
        let inputs = self.pre.iter().map(|a| (ArcKind::Input, a));
        let outputs = self.post.iter().map(|a| (ArcKind::Output, a));
        let inhibitors = self.inhibit.iter().map(|a| (ArcKind::Inhibitor, a));
        inputs.chain(outputs).chain(inhibitors)
    }
}

impl Net {
    /// An empty net called `id`.
    pub fn new(id: &str) -> Self {
        Net {
            id: id.to_owned(),
            ..Net::default()
        }
    }

    /// Adds a place (named as its id) holding `tokens` initially.
    pub fn add_place(&mut self, id: &str, tokens: u32) -> Result<PlaceId, NetError> {
        if self.place(id).is_some() {
            return Err(NetError::DuplicatePlace(id.to_owned()));
        }
        self.places.push(Place {
            id: id.to_owned(),
            name: id.to_owned(),
            initial: tokens,
            capacity: None,
        });
        Ok(PlaceId(self.places.len() - 1))
    }

    /// Adds a transition (named as its id) with no arcs.
    pub fn add_transition(
        &mut self,
        id: &str,
        label: Option<&str>,
    ) -> Result<TransitionId, NetError> {
        if self.transition(id).is_some() {
            return Err(NetError::DuplicateTransition(id.to_owned()));
        }
        self.transitions.push(Transition {
            id: id.to_owned(),
            name: id.to_owned(),
            label: label.map(str::to_owned),
            pre: Vec::new(),
            post: Vec::new(),
            inhibit: Vec::new(),
        });
        Ok(TransitionId(self.transitions.len() - 1))
    }

    /// Adds an arc of `kind` between place `place` and transition `t`. Two
    /// input or output arcs between the same nodes add their weights; two
    /// inhibitor arcs keep the stricter (smaller) threshold.
    pub fn add_arc(
        &mut self,
        kind: ArcKind,
        place: &str,
        t: TransitionId,
        weight: u32,
    ) -> Result<(), NetError> {
        let transition = self.transitions[t.0].id.clone();
        if weight == 0 {
            return Err(NetError::ZeroWeight {
                transition,
                place: place.to_owned(),
            });
        }
        let p = self.place(place).ok_or_else(|| NetError::UnknownPlace {
            transition,
            place: place.to_owned(),
        })?;
        let tr = &mut self.transitions[t.0];
        let arcs = match kind {
            ArcKind::Input => &mut tr.pre,
            ArcKind::Output => &mut tr.post,
            ArcKind::Inhibitor => &mut tr.inhibit,
        };
        match arcs.iter_mut().find(|a| a.place == p) {
            Some(a) if kind == ArcKind::Inhibitor => a.weight = a.weight.min(weight),
            Some(a) => a.weight = a.weight.saturating_add(weight),
            None => arcs.push(Arc { place: p, weight }),
        }
        Ok(())
    }

    /// Adds a transition with its input and output arcs, each `(place id, weight)`.
    pub fn add_transition_with(
        &mut self,
        id: &str,
        label: Option<&str>,
        pre: &[(&str, u32)],
        post: &[(&str, u32)],
    ) -> Result<TransitionId, NetError> {
        let t = self.add_transition(id, label)?;
        let arcs = pre
            .iter()
            .map(|a| (ArcKind::Input, a))
            .chain(post.iter().map(|a| (ArcKind::Output, a)));
        for (kind, &(place, weight)) in arcs {
            if let Err(e) = self.add_arc(kind, place, t, weight) {
                self.transitions.pop();
                return Err(e);
            }
        }
        Ok(t)
    }

    /// The place with id `id`.
    pub fn place(&self, id: &str) -> Option<PlaceId> {
        self.places.iter().position(|p| p.id == id).map(PlaceId)
    }

    /// The transition with id `id`.
    pub fn transition(&self, id: &str) -> Option<TransitionId> {
        self.transitions
            .iter()
            .position(|t| t.id == id)
            .map(TransitionId)
    }

    /// The initial marking m0.
    pub fn initial_marking(&self) -> Marking {
        Marking(self.places.iter().map(|p| p.initial).collect())
    }

    /// Whether `t` may fire at `m`: every input place holds the arc weight,
    /// every inhibiting place holds less than its weight, and no capacity
    /// would be exceeded.
    pub fn is_enabled(&self, m: &Marking, t: TransitionId) -> bool {
        let tr = &self.transitions[t.0];
        tr.pre.iter().all(|a| m.0[a.place.0] >= a.weight)
            && tr.inhibit.iter().all(|a| m.0[a.place.0] < a.weight)
            && tr.post.iter().all(|a| {
                let Some(cap) = self.places[a.place.0].capacity else {
                    return true;
                };
                let taken = tr
                    .pre
                    .iter()
                    .find(|b| b.place == a.place)
                    .map_or(0, |b| b.weight);
                u64::from(m.0[a.place.0]) - u64::from(taken) + u64::from(a.weight) <= u64::from(cap)
            })
    }

    /// Transitions enabled at `m`, in index order.
    pub fn enabled<'a>(&'a self, m: &'a Marking) -> impl Iterator<Item = TransitionId> + 'a {
        (0..self.transitions.len())
            .map(TransitionId)
            .filter(move |&t| self.is_enabled(m, t))
    }

    /// The marking reached by firing `t` at `m`: m' = m − pre(t) + post(t).
    pub fn fire(&self, m: &Marking, t: TransitionId) -> Result<Marking, NetError> {
        let tr = &self.transitions[t.0];
        if !self.is_enabled(m, t) {
            return Err(NetError::NotEnabled(tr.id.clone()));
        }
        let mut next = m.clone();
        for a in &tr.pre {
            next.0[a.place.0] -= a.weight;
        }
        for a in &tr.post {
            let slot = &mut next.0[a.place.0];
            *slot = slot
                .checked_add(a.weight)
                .ok_or_else(|| NetError::Overflow(tr.id.clone()))?;
        }
        Ok(next)
    }

    /// The incidence matrix C (places × transitions): C[p][t] = post − pre.
    pub fn incidence(&self) -> Vec<Vec<i64>> {
        let mut c = vec![vec![0i64; self.transitions.len()]; self.places.len()];
        for (t, tr) in self.transitions.iter().enumerate() {
            for a in &tr.pre {
                c[a.place.0][t] -= i64::from(a.weight);
            }
            for a in &tr.post {
                c[a.place.0][t] += i64::from(a.weight);
            }
        }
        c
    }

    /// The marked places of `m`, by id, for messages people read.
    pub fn describe<'a>(&'a self, m: &'a Marking) -> MarkingDisplay<'a> {
        MarkingDisplay {
            net: self,
            marking: m,
        }
    }
}

/// A marking printed as `{place, place×2}`.
pub struct MarkingDisplay<'a> {
    net: &'a Net,
    marking: &'a Marking,
}

impl fmt::Display for MarkingDisplay<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let marked: Vec<String> = self
            .marking
            .0
            .iter()
            .zip(&self.net.places)
            .filter(|(n, _)| **n > 0)
            .map(|(n, p)| {
                if *n == 1 {
                    p.id.clone()
                } else {
                    format!("{}×{n}", p.id)
                }
            })
            .collect();
        write!(f, "{{{}}}", marked.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn mutex() -> Net {
        let mut n = Net::new("mutex");
        for (p, m) in [
            ("idle_a", 1),
            ("busy_a", 0),
            ("idle_b", 1),
            ("busy_b", 0),
            ("free", 1),
        ] {
            n.add_place(p, m).unwrap();
        }
        let take = Some("take");
        let give = Some("give");
        n.add_transition_with(
            "take_a",
            take,
            &[("idle_a", 1), ("free", 1)],
            &[("busy_a", 1)],
        )
        .unwrap();
        n.add_transition_with(
            "give_a",
            give,
            &[("busy_a", 1)],
            &[("idle_a", 1), ("free", 1)],
        )
        .unwrap();
        n.add_transition_with(
            "take_b",
            take,
            &[("idle_b", 1), ("free", 1)],
            &[("busy_b", 1)],
        )
        .unwrap();
        n.add_transition_with(
            "give_b",
            give,
            &[("busy_b", 1)],
            &[("idle_b", 1), ("free", 1)],
        )
        .unwrap();
        n
    }

    #[test]
    fn firing_follows_the_arcs() {
        let n = mutex();
        let m0 = n.initial_marking();
        let take_a = n.transition("take_a").unwrap();
        let take_b = n.transition("take_b").unwrap();
        let m1 = n.fire(&m0, take_a).unwrap();
        assert_eq!(m1.0, vec![0, 1, 1, 0, 0]);
        assert_eq!(
            n.fire(&m1, take_b),
            Err(NetError::NotEnabled("take_b".into()))
        );
        assert_eq!(n.describe(&m1).to_string(), "{busy_a, idle_b}");
    }

    #[test]
    fn inhibitors_and_capacities_disable() {
        let mut n = Net::new("guarded");
        n.add_place("p", 1).unwrap();
        n.add_place("q", 0).unwrap();
        let t = n.add_transition_with("t", None, &[], &[("q", 1)]).unwrap();
        n.add_arc(ArcKind::Inhibitor, "p", t, 1).unwrap();
        let m0 = n.initial_marking();
        assert!(!n.is_enabled(&m0, t), "p is marked, so t is inhibited");
        let free = Marking(vec![0, 0]);
        assert!(n.is_enabled(&free, t));
        n.places[1].capacity = Some(1);
        let full = n.fire(&free, t).unwrap();
        assert!(!n.is_enabled(&full, t), "q is at its capacity");
    }

    #[test]
    fn bad_arcs_are_named() {
        let mut n = mutex();
        assert_eq!(
            n.add_transition_with("x", None, &[("nowhere", 1)], &[]),
            Err(NetError::UnknownPlace {
                transition: "x".into(),
                place: "nowhere".into()
            })
        );
        assert!(n.transition("x").is_none(), "a failed add leaves no trace");
        assert!(matches!(
            n.add_transition_with("y", None, &[("free", 0)], &[]),
            Err(NetError::ZeroWeight { .. })
        ));
        assert_eq!(
            n.add_place("free", 0),
            Err(NetError::DuplicatePlace("free".into()))
        );
    }

    proptest! {
        /// The state equation: firing t changes m by column t of the incidence matrix.
        #[test]
        fn firing_obeys_the_state_equation(
            choices in proptest::collection::vec(0usize..4, 0..40)
        ) {
            let n = mutex();
            let c = n.incidence();
            let mut m = n.initial_marking();
            for pick in choices {
                let enabled: Vec<_> = n.enabled(&m).collect();
                if enabled.is_empty() { break; }
                let t = enabled[pick % enabled.len()];
                let next = n.fire(&m, t).unwrap();
                for (p, row) in c.iter().enumerate() {
                    prop_assert_eq!(i64::from(next.0[p]), i64::from(m.0[p]) + row[t.0]);
                }
                // mutual exclusion holds in every reachable marking
                prop_assert!(next.0[1] + next.0[3] <= 1);
                m = next;
            }
        }
    }
}
