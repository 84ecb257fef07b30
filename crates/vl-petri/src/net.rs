//! Place/transition nets and their firing rule.
//!
//! A net is kept as its pre- and post-incidence lists (arc weights per
//! transition) because the firing rule only ever needs "what does t take and
//! what does t give": enabling is a scan of `pre[t]`, firing adds `post[t]`.

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

/// A transition: its name, the label it synchronises on, and its arcs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transition {
    pub name: String,
    /// The event this transition stands for; transitions of different nets
    /// with the same label fire together when nets are composed.
    pub label: String,
    /// Input arcs: tokens taken when it fires.
    pub pre: Vec<Arc>,
    /// Output arcs: tokens given when it fires.
    pub post: Vec<Arc>,
}

/// A place/transition net with its initial marking.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Net {
    pub places: Vec<String>,
    pub transitions: Vec<Transition>,
    pub initial: Vec<u32>,
}

/// Why a net could not be built or a transition could not fire.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum NetError {
    #[error("place '{0}' is defined twice")]
    DuplicatePlace(String),
    #[error("transition '{0}' is defined twice")]
    DuplicateTransition(String),
    #[error("transition '{transition}' names unknown place '{place}'")]
    UnknownPlace { transition: String, place: String },
    #[error("arc between '{place}' and '{transition}' has weight 0")]
    ZeroWeight { transition: String, place: String },
    #[error("transition '{0}' is not enabled")]
    NotEnabled(String),
    #[error("firing '{0}' would overflow a place's token count")]
    Overflow(String),
}

impl Net {
    /// Adds a place with `tokens` initial tokens.
    pub fn add_place(&mut self, name: &str, tokens: u32) -> Result<PlaceId, NetError> {
        if self.place(name).is_some() {
            return Err(NetError::DuplicatePlace(name.to_owned()));
        }
        self.places.push(name.to_owned());
        self.initial.push(tokens);
        Ok(PlaceId(self.places.len() - 1))
    }

    /// Adds a transition taking `pre` and giving `post`, each a list of
    /// `(place name, weight)`.
    pub fn add_transition(
        &mut self,
        name: &str,
        label: &str,
        pre: &[(&str, u32)],
        post: &[(&str, u32)],
    ) -> Result<TransitionId, NetError> {
        if self.transition(name).is_some() {
            return Err(NetError::DuplicateTransition(name.to_owned()));
        }
        let arcs = |list: &[(&str, u32)]| -> Result<Vec<Arc>, NetError> {
            list.iter()
                .map(|&(place, weight)| {
                    if weight == 0 {
                        return Err(NetError::ZeroWeight {
                            transition: name.to_owned(),
                            place: place.to_owned(),
                        });
                    }
                    let id = self.place(place).ok_or_else(|| NetError::UnknownPlace {
                        transition: name.to_owned(),
                        place: place.to_owned(),
                    })?;
                    Ok(Arc { place: id, weight })
                })
                .collect()
        };
        let transition = Transition {
            name: name.to_owned(),
            label: label.to_owned(),
            pre: arcs(pre)?,
            post: arcs(post)?,
        };
        self.transitions.push(transition);
        Ok(TransitionId(self.transitions.len() - 1))
    }

    /// The place called `name`.
    pub fn place(&self, name: &str) -> Option<PlaceId> {
        self.places.iter().position(|p| p == name).map(PlaceId)
    }

    /// The transition called `name`.
    pub fn transition(&self, name: &str) -> Option<TransitionId> {
        self.transitions
            .iter()
            .position(|t| t.name == name)
            .map(TransitionId)
    }

    /// The initial marking m0.
    pub fn initial_marking(&self) -> Marking {
        Marking(self.initial.clone())
    }

    /// Whether `t` may fire at `m`: every input place holds at least the arc weight.
    pub fn is_enabled(&self, m: &Marking, t: TransitionId) -> bool {
        self.transitions[t.0]
            .pre
            .iter()
            .all(|a| m.0[a.place.0] >= a.weight)
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
            return Err(NetError::NotEnabled(tr.name.clone()));
        }
        let mut next = m.clone();
        for a in &tr.pre {
            next.0[a.place.0] -= a.weight;
        }
        for a in &tr.post {
            let slot = &mut next.0[a.place.0];
            *slot = slot
                .checked_add(a.weight)
                .ok_or_else(|| NetError::Overflow(tr.name.clone()))?;
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

    /// The marked places of `m`, by name, for messages people read.
    pub fn describe(&self, m: &Marking) -> MarkingDisplay<'_> {
        MarkingDisplay {
            net: self,
            marking: m.clone(),
        }
    }
}

/// A marking printed as `{place, place×2}`.
pub struct MarkingDisplay<'a> {
    net: &'a Net,
    marking: Marking,
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
                    p.clone()
                } else {
                    format!("{p}×{n}")
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
        let mut n = Net::default();
        n.add_place("idle_a", 1).unwrap();
        n.add_place("busy_a", 0).unwrap();
        n.add_place("idle_b", 1).unwrap();
        n.add_place("busy_b", 0).unwrap();
        n.add_place("free", 1).unwrap();
        n.add_transition(
            "take_a",
            "take",
            &[("idle_a", 1), ("free", 1)],
            &[("busy_a", 1)],
        )
        .unwrap();
        n.add_transition(
            "give_a",
            "give",
            &[("busy_a", 1)],
            &[("idle_a", 1), ("free", 1)],
        )
        .unwrap();
        n.add_transition(
            "take_b",
            "take",
            &[("idle_b", 1), ("free", 1)],
            &[("busy_b", 1)],
        )
        .unwrap();
        n.add_transition(
            "give_b",
            "give",
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
    fn bad_arcs_are_named() {
        let mut n = mutex();
        assert_eq!(
            n.add_transition("x", "x", &[("nowhere", 1)], &[]),
            Err(NetError::UnknownPlace {
                transition: "x".into(),
                place: "nowhere".into()
            })
        );
        assert!(matches!(
            n.add_transition("y", "y", &[("free", 0)], &[]),
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
