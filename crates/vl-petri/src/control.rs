//! Supervisory control by Petri-net controllers: given a plant net and
//! constraints on it, add the places and arcs that enforce them, leaving the
//! plant's own places and transitions unchanged.
//!
//! - Linear marking constraints L·m ≤ b by place invariants (Yamalidou et
//!   al. 1996): a monitor place with incidence D_c = −L·D and initial marking
//!   m_c0 = b − L·m0 keeps L·m + m_c = b, so it holds a token for every unit
//!   of slack and disables exactly the firings that would overdraw it. With
//!   every transition controllable and observable this is maximally
//!   permissive.
//! - Uncontrollable transitions (which a controller may not disable) and
//!   unobservable ones (which it cannot see) need L·D ≤ 0 on the former and
//!   L·D = 0 on the latter. When a constraint lacks that, it is tightened
//!   as Moody and Antsaklis do, to L' = L + R₁ with R₁ ≥ 0 (their R₂ = 1
//!   case): weight is added to places feeding an offending transition until
//!   every uncontrollable one cannot raise L'·m and every unobservable one
//!   leaves it unchanged. L'·m ≤ b implies L·m ≤ b, so the controller stays
//!   correct, at the price of permissiveness. When no such R₁ is found, or
//!   the initial marking already breaks L'·m ≤ b, synthesis is refused.
//! - Logical constraints "if p is marked then t must not fire" in safe
//!   ordinary nets, the thesis's method: an inhibitor arc p ⊸ t.

use std::fmt;

use thiserror::Error;

use crate::net::{ArcKind, Net, PlaceId, TransitionId};

/// A constraint on the plant, as the user writes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Constraint {
    /// Σ coefficient·m(place) ≤ bound.
    Linear {
        terms: Vec<(String, i64)>,
        bound: i64,
    },
    /// If `place` is marked, `transition` must not fire.
    IfThenNot { place: String, transition: String },
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ControlError {
    #[error("constraint '{constraint}' does not parse: {why}")]
    Syntax { constraint: String, why: String },
    #[error("constraint '{constraint}' names unknown place '{place}'")]
    UnknownPlace { constraint: String, place: String },
    #[error("constraint '{constraint}' names unknown transition '{transition}'")]
    UnknownTransition {
        constraint: String,
        transition: String,
    },
    #[error("unknown transition '{0}' in the uncontrollable or unobservable list")]
    UnknownListed(String),
    #[error(
        "constraint '{constraint}' is already violated by the initial marking \
         (L·m0 = {value} > {bound})"
    )]
    ViolatedInitially {
        constraint: String,
        value: i64,
        bound: i64,
    },
    #[error("no controller enforces '{constraint}': {why}")]
    NoController { constraint: String, why: String },
}

impl fmt::Display for Constraint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Constraint::Linear { terms, bound } => {
                for (i, (place, k)) in terms.iter().enumerate() {
                    let sign = match (i, *k < 0) {
                        (0, false) => "",
                        (0, true) => "-",
                        (_, false) => " + ",
                        (_, true) => " - ",
                    };
                    match k.unsigned_abs() {
                        1 => write!(f, "{sign}{place}")?,
                        n => write!(f, "{sign}{n}*{place}")?,
                    }
                }
                write!(f, " <= {bound}")
            }
            Constraint::IfThenNot { place, transition } => {
                write!(f, "if {place} then not {transition}")
            }
        }
    }
}

impl Constraint {
    /// Parses `p1 + 2*p3 <= 1`, `3 p1 - p2 >= -1` or `if p2 then not t4`.
    pub fn parse(text: &str) -> Result<Constraint, ControlError> {
        let syntax = |why: &str| ControlError::Syntax {
            constraint: text.to_owned(),
            why: why.to_owned(),
        };
        let words: Vec<&str> = text.split_whitespace().collect();
        if words.first() == Some(&"if") {
            return match words[..] {
                ["if", place, "then", "not", transition] => Ok(Constraint::IfThenNot {
                    place: place.to_owned(),
                    transition: transition.to_owned(),
                }),
                _ => Err(syntax("expected 'if PLACE then not TRANSITION'")),
            };
        }
        let (lhs, rhs, flip) = if let Some((l, r)) = text.split_once("<=") {
            (l, r, false)
        } else if let Some((l, r)) = text.split_once(">=") {
            (l, r, true)
        } else {
            return Err(syntax("expected '<=' or '>='"));
        };
        let bound: i64 = rhs
            .trim()
            .parse()
            .map_err(|_| syntax("the right-hand side must be a whole number"))?;
        // Split into signed terms: "p1 + 2*p3 - p4" → [+p1, +2*p3, -p4].
        let spaced = lhs.replace('+', " + ").replace('-', " - ");
        let mut terms: Vec<(String, i64)> = Vec::new();
        let mut sign = 1i64;
        let mut pending: Option<i64> = None;
        let mut dangling = false;
        for token in spaced.split_whitespace() {
            dangling = matches!(token, "+" | "-");
            match token {
                "+" => sign = 1,
                "-" => sign = -sign,
                _ => {
                    let (coef, place) = match token.split_once('*') {
                        Some((c, p)) => (Some(c.trim()), p.trim()),
                        None => (None, token),
                    };
                    if let Ok(n) = place.parse::<i64>() {
                        if coef.is_some() || pending.is_some() {
                            return Err(syntax("a coefficient must multiply a place"));
                        }
                        pending = Some(n);
                        continue;
                    }
                    let k = match (coef, pending.take()) {
                        (Some(c), None) => c
                            .parse::<i64>()
                            .map_err(|_| syntax("coefficients must be whole numbers"))?,
                        (None, Some(n)) => n,
                        (None, None) => 1,
                        (Some(_), Some(_)) => return Err(syntax("two coefficients for one place")),
                    };
                    if place.is_empty()
                        || !place
                            .chars()
                            .all(|c| c.is_alphanumeric() || "_.:".contains(c))
                    {
                        return Err(syntax(&format!("'{place}' is not a place id")));
                    }
                    terms.push((place.to_owned(), sign * k));
                    sign = 1;
                }
            }
        }
        if pending.is_some() {
            return Err(syntax("a coefficient must multiply a place"));
        }
        if dangling {
            return Err(syntax("a sign with no term after it"));
        }
        if terms.is_empty() {
            return Err(syntax("no places on the left-hand side"));
        }
        Ok(if flip {
            Constraint::Linear {
                terms: terms.into_iter().map(|(p, k)| (p, -k)).collect(),
                bound: -bound,
            }
        } else {
            Constraint::Linear { terms, bound }
        })
    }
}

/// Which transitions the controller may not disable or cannot see.
#[derive(Debug, Clone, Default)]
pub struct Limits {
    pub uncontrollable: Vec<String>,
    pub unobservable: Vec<String>,
}

/// What synthesis added, for the reader.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Added {
    /// A monitor place enforcing a linear constraint, possibly tightened.
    Monitor {
        place: String,
        initial: u32,
        enforced: Constraint,
    },
    /// An inhibitor arc place ⊸ transition.
    Inhibitor { place: String, transition: String },
}

/// The plant with controllers for every constraint added, and a list of what was added.
pub fn synthesize(
    plant: &Net,
    constraints: &[Constraint],
    limits: &Limits,
) -> Result<(Net, Vec<Added>), ControlError> {
    let lookup = |id: &str| {
        plant
            .transition(id)
            .ok_or_else(|| ControlError::UnknownListed(id.to_owned()))
    };
    let uncontrollable: Vec<TransitionId> = limits
        .uncontrollable
        .iter()
        .map(|t| lookup(t))
        .collect::<Result<_, _>>()?;
    let unobservable: Vec<TransitionId> = limits
        .unobservable
        .iter()
        .map(|t| lookup(t))
        .collect::<Result<_, _>>()?;
    let mut net = plant.clone();
    let mut added = Vec::new();
    let d = plant.incidence();
    for (n, constraint) in constraints.iter().enumerate() {
        let text = constraint.to_string();
        match constraint {
            Constraint::Linear { terms, bound } => {
                let limits = (&d[..], &uncontrollable[..], &unobservable[..]);
                added.push(monitor(plant, &mut net, limits, n, terms, *bound, text)?);
            }
            Constraint::IfThenNot { place, transition } => {
                added.push(inhibitor(
                    plant,
                    &mut net,
                    &uncontrollable,
                    place,
                    transition,
                    text,
                )?);
            }
        }
    }
    Ok((net, added))
}

/// The monitor place that enforces constraint `n`, `terms · m ≤ bound`
/// (its words `text`), added to `net`; `limits` are the plant's incidence
/// matrix and its uncontrollable and unobservable transitions.
fn monitor(
    plant: &Net,
    net: &mut Net,
    (d, uncontrollable, unobservable): (&[Vec<i64>], &[TransitionId], &[TransitionId]),
    n: usize,
    terms: &[(String, i64)],
    bound: i64,
    text: String,
) -> Result<Added, ControlError> {
    let mut l = vec![0i64; plant.places.len()];
    for (place, k) in terms {
        let p = plant
            .place(place)
            .ok_or_else(|| ControlError::UnknownPlace {
                constraint: text.clone(),
                place: place.clone(),
            })?;
        l[p.0] += k;
    }
    let l = admissible(d, l, uncontrollable, unobservable).map_err(|why| {
        ControlError::NoController {
            constraint: text.clone(),
            why,
        }
    })?;
    let value: i64 = l
        .iter()
        .zip(&plant.places)
        .map(|(k, p)| k * i64::from(p.initial))
        .sum();
    if value > bound {
        return Err(ControlError::ViolatedInitially {
            constraint: text,
            value,
            bound,
        });
    }
    let id = unique_id(net, &format!("monitor{}", n + 1));
    let initial = u32::try_from(bound - value).map_err(|_| ControlError::NoController {
        constraint: text.clone(),
        why: "the monitor would need more than 2³² tokens".into(),
    })?;
    let p = net.add_place(&id, initial).expect("the id is unused");
    let enforced = Constraint::Linear {
        terms: l
            .iter()
            .enumerate()
            .filter(|(_, k)| **k != 0)
            .map(|(i, &k)| (plant.places[i].id.clone(), k))
            .collect(),
        bound,
    };
    net.places[p.0].name = format!("monitor: {enforced}");
    for t in 0..plant.transitions.len() {
        // D_c[t] = −(L·D)[t]
        let change = -effect(d, &l, t);
        let weight = u32::try_from(change.unsigned_abs()).unwrap_or(u32::MAX);
        let kind = match change.signum() {
            1 => ArcKind::Output,
            -1 => ArcKind::Input,
            _ => continue,
        };
        net.add_arc(kind, &id, TransitionId(t), weight)
            .expect("monitor and transition exist");
    }
    Ok(Added::Monitor {
        place: id,
        initial,
        enforced,
    })
}

/// The inhibitor arc that keeps `transition` from firing while `place` is
/// marked, added to `net`.
fn inhibitor(
    plant: &Net,
    net: &mut Net,
    uncontrollable: &[TransitionId],
    place: &str,
    transition: &str,
    text: String,
) -> Result<Added, ControlError> {
    let p: PlaceId = plant
        .place(place)
        .ok_or_else(|| ControlError::UnknownPlace {
            constraint: text.clone(),
            place: place.to_owned(),
        })?;
    let t = plant
        .transition(transition)
        .ok_or_else(|| ControlError::UnknownTransition {
            constraint: text.clone(),
            transition: transition.to_owned(),
        })?;
    if uncontrollable.contains(&t) {
        return Err(ControlError::NoController {
            constraint: text,
            why: format!("'{transition}' is uncontrollable, so nothing may disable it"),
        });
    }
    net.add_arc(ArcKind::Inhibitor, &plant.places[p.0].id, t, 1)
        .expect("place and transition exist");
    Ok(Added::Inhibitor {
        place: place.to_owned(),
        transition: transition.to_owned(),
    })
}

/// L tightened to L + R₁ (R₁ ≥ 0) so that uncontrollable transitions cannot
/// raise L·m and unobservable ones do not change it.
fn admissible(
    d: &[Vec<i64>],
    mut l: Vec<i64>,
    uncontrollable: &[TransitionId],
    unobservable: &[TransitionId],
) -> Result<Vec<i64>, String> {
    let effect = |l: &[i64], t: usize| effect(d, l, t);
    // Each round fixes one offending transition; a bound on rounds catches
    // cycles of uncontrollable transitions that push weight around forever.
    for _ in 0..(d.len() + 1) * (uncontrollable.len() + unobservable.len() + 1) * 4 {
        let too_high = uncontrollable
            .iter()
            .chain(unobservable)
            .map(|t| t.0)
            .find(|&t| effect(&l, t) > 0);
        let too_low = unobservable
            .iter()
            .map(|t| t.0)
            .find(|&t| effect(&l, t) < 0);
        match (too_high, too_low) {
            (None, None) => return Ok(l),
            (Some(t), _) => {
                // Weigh an input place of t: its tokens leaving offsets the rise.
                let excess = effect(&l, t);
                let Some(p) = (0..d.len())
                    .filter(|&p| d[p][t] < 0)
                    .max_by_key(|&p| -d[p][t])
                else {
                    return Err(format!(
                        "transition {t} raises the constrained count and takes no tokens to offset it"
                    ));
                };
                l[p] += (excess.unsigned_abs().div_ceil(d[p][t].unsigned_abs())) as i64;
            }
            (None, Some(t)) => {
                let deficit = -effect(&l, t);
                let Some(p) = (0..d.len())
                    .filter(|&p| d[p][t] > 0)
                    .max_by_key(|&p| d[p][t])
                else {
                    return Err(format!(
                        "unobservable transition {t} lowers the constrained count"
                    ));
                };
                l[p] += (deficit.unsigned_abs().div_ceil(d[p][t].unsigned_abs())) as i64;
            }
        }
        if l.iter().any(|k| k.unsigned_abs() > 1 << 40) {
            break;
        }
    }
    Err("the uncontrollable and unobservable transitions admit no tightening L + R₁".into())
}

/// (L·D)[t]: how firing t changes the constrained count L·m.
fn effect(d: &[Vec<i64>], l: &[i64], t: usize) -> i64 {
    l.iter().zip(d).map(|(k, row)| k * row[t]).sum()
}

fn unique_id(net: &Net, base: &str) -> String {
    let taken = |id: &str| net.place(id).is_some() || net.transition(id).is_some();
    if !taken(base) {
        return base.to_owned();
    }
    (2..)
        .map(|i| format!("{base}_{i}"))
        .find(|id| !taken(id))
        .expect("some suffix is free")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_two_kinds() {
        assert_eq!(
            Constraint::parse("p1 + 2*p3 <= 1").unwrap(),
            Constraint::Linear {
                terms: vec![("p1".into(), 1), ("p3".into(), 2)],
                bound: 1
            }
        );
        assert_eq!(
            Constraint::parse("3 a - b >= -2").unwrap(),
            Constraint::Linear {
                terms: vec![("a".into(), -3), ("b".into(), 1)],
                bound: 2
            }
        );
        assert_eq!(
            Constraint::parse("if p2 then not t4").unwrap(),
            Constraint::IfThenNot {
                place: "p2".into(),
                transition: "t4".into()
            }
        );
        assert!(matches!(
            Constraint::parse("p1 + <= 1"),
            Err(ControlError::Syntax { .. })
        ));
        assert!(matches!(
            Constraint::parse("2 <= 1"),
            Err(ControlError::Syntax { .. })
        ));
        assert_eq!(
            Constraint::parse("-p1 + 2*p3 <= 1").unwrap().to_string(),
            "-p1 + 2*p3 <= 1"
        );
        assert!(matches!(
            Constraint::parse("p1 < 1"),
            Err(ControlError::Syntax { .. })
        ));
        assert!(matches!(
            Constraint::parse("if p then t"),
            Err(ControlError::Syntax { .. })
        ));
        assert_eq!(
            Constraint::parse("p1 + 2*p3 <= 1").unwrap().to_string(),
            "p1 + 2*p3 <= 1"
        );
    }

    /// Two processes share a resource; the constraint busy_a + busy_b <= 1 is mutual exclusion.
    fn plant() -> Net {
        let mut n = Net::new("two");
        for (p, m) in [("idle_a", 1), ("busy_a", 0), ("idle_b", 1), ("busy_b", 0)] {
            n.add_place(p, m).unwrap();
        }
        n.add_transition_with("enter_a", None, &[("idle_a", 1)], &[("busy_a", 1)])
            .unwrap();
        n.add_transition_with("leave_a", None, &[("busy_a", 1)], &[("idle_a", 1)])
            .unwrap();
        n.add_transition_with("enter_b", None, &[("idle_b", 1)], &[("busy_b", 1)])
            .unwrap();
        n.add_transition_with("leave_b", None, &[("busy_b", 1)], &[("idle_b", 1)])
            .unwrap();
        n
    }

    #[test]
    fn a_monitor_enforces_mutual_exclusion() {
        let c = Constraint::parse("busy_a + busy_b <= 1").unwrap();
        let (net, added) = synthesize(&plant(), &[c], &Limits::default()).unwrap();
        assert_eq!(net.places.len(), 5);
        assert!(
            matches!(&added[0], Added::Monitor { place, initial: 1, .. } if place == "monitor1")
        );
        let monitor = &net.places[4];
        assert_eq!(monitor.name, "monitor: busy_a + busy_b <= 1");
        let enter_a = &net.transitions[0];
        assert_eq!(enter_a.pre.iter().filter(|a| a.place.0 == 4).count(), 1);
    }

    #[test]
    fn uncontrollable_entries_tighten_the_constraint() {
        // enter_b cannot be disabled: the controller must count idle_b too.
        let c = Constraint::parse("busy_a + busy_b <= 1").unwrap();
        let limits = Limits {
            uncontrollable: vec!["enter_b".into()],
            ..Limits::default()
        };
        let (net, added) = synthesize(&plant(), &[c], &limits).unwrap();
        let Added::Monitor {
            enforced, initial, ..
        } = &added[0]
        else {
            panic!()
        };
        assert_eq!(enforced.to_string(), "busy_a + idle_b + busy_b <= 1");
        assert_eq!(*initial, 0);
        // The monitor never takes from the uncontrollable transition.
        assert!(net.transitions[2].pre.iter().all(|a| a.place.0 != 4));
    }

    #[test]
    fn impossible_goals_are_refused_by_name() {
        let bad = Constraint::parse("busy_a + ghost <= 1").unwrap();
        assert_eq!(
            synthesize(&plant(), &[bad], &Limits::default()).unwrap_err(),
            ControlError::UnknownPlace {
                constraint: "busy_a + ghost <= 1".into(),
                place: "ghost".into()
            }
        );
        let violated = Constraint::parse("idle_a <= 0").unwrap();
        assert!(matches!(
            synthesize(&plant(), &[violated], &Limits::default()),
            Err(ControlError::ViolatedInitially {
                value: 1,
                bound: 0,
                ..
            })
        ));
        let inhibit_uncontrollable = Constraint::parse("if busy_a then not enter_b").unwrap();
        let limits = Limits {
            uncontrollable: vec!["enter_b".into()],
            ..Limits::default()
        };
        assert!(matches!(
            synthesize(&plant(), &[inhibit_uncontrollable], &limits),
            Err(ControlError::NoController { .. })
        ));
    }
}
