//! Composing subsystems into one net, as the thesis merges a lab's
//! functionalities: synchronous transition composition (Kumar & Holloway
//! 1996) and parallel place fusion (Murata 1989).
//!
//! Every place and transition keeps its origin in its id (`net.node`), so a
//! reader of the composed net can trace each element back. Transitions of
//! different nets carrying the same label fuse into one that needs — and
//! does — what all of them need and do; when a label has several transitions
//! in one net, every combination becomes its own fused transition. Unlabelled
//! transitions, and labels only one net uses, stay as they are.

use std::collections::{BTreeMap, HashMap};

use thiserror::Error;

use crate::net::{ArcKind, Net, TransitionId};

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ComposeError {
    #[error("nothing to compose")]
    Empty,
    #[error("label '{label}' would fuse into more than {limit} transitions")]
    TooManyCombinations { label: String, limit: usize },
}

/// Fused transitions one label may produce before composition gives up.
const MAX_COMBINATIONS: usize = 100_000;

/// The synchronous composition of `nets`.
pub fn compose(nets: &[Net]) -> Result<Net, ComposeError> {
    if nets.is_empty() {
        return Err(ComposeError::Empty);
    }
    let prefixes = prefixes(nets);
    let id = prefixes.join("+");
    let mut out = Net::new(&id);
    for (net, prefix) in nets.iter().zip(&prefixes) {
        for p in &net.places {
            let q = out
                .add_place(&format!("{prefix}.{}", p.id), p.initial)
                .expect("prefixed ids are unique");
            out.places[q.0].name = format!("{prefix}.{}", p.name);
            out.places[q.0].capacity = p.capacity;
        }
    }
    // Which nets use each label, and with which transitions.
    let mut by_label: BTreeMap<&str, Vec<(usize, Vec<usize>)>> = BTreeMap::new();
    for (n, net) in nets.iter().enumerate() {
        for (t, tr) in net.transitions.iter().enumerate() {
            if let Some(label) = &tr.label {
                let users = by_label.entry(label.as_str()).or_default();
                match users.last_mut() {
                    Some((last, ts)) if *last == n => ts.push(t),
                    _ => users.push((n, vec![t])),
                }
            }
        }
    }
    let shared = |label: &Option<String>| label.as_deref().is_some_and(|l| by_label[l].len() > 1);
    // Transitions that do not synchronise, in net order.
    for (net, prefix) in nets.iter().zip(&prefixes) {
        for tr in net.transitions.iter().filter(|t| !shared(&t.label)) {
            let t = out
                .add_transition(&format!("{prefix}.{}", tr.id), tr.label.as_deref())
                .expect("prefixed ids are unique");
            out.transitions[t.0].name = format!("{prefix}.{}", tr.name);
            copy_arcs(&mut out, t, net, prefix, tr);
        }
    }
    // One fused transition per combination of same-labelled transitions.
    for (label, users) in by_label.iter().filter(|(_, users)| users.len() > 1) {
        let total: usize = users.iter().map(|(_, ts)| ts.len()).product();
        if total > MAX_COMBINATIONS {
            return Err(ComposeError::TooManyCombinations {
                label: (*label).to_owned(),
                limit: MAX_COMBINATIONS,
            });
        }
        for k in 0..total {
            let mut rest = k;
            let chosen: Vec<(usize, usize)> = users
                .iter()
                .map(|(n, ts)| {
                    let pick = ts[rest % ts.len()];
                    rest /= ts.len();
                    (*n, pick)
                })
                .collect();
            let id = chosen
                .iter()
                .map(|&(n, t)| format!("{}.{}", prefixes[n], nets[n].transitions[t].id))
                .collect::<Vec<_>>()
                .join("|");
            let fused = out
                .add_transition(&id, Some(label))
                .expect("fused ids are unique");
            for &(n, t) in &chosen {
                copy_arcs(
                    &mut out,
                    fused,
                    &nets[n],
                    &prefixes[n],
                    &nets[n].transitions[t],
                );
            }
        }
    }
    Ok(out)
}

fn copy_arcs(out: &mut Net, t: TransitionId, net: &Net, prefix: &str, tr: &crate::net::Transition) {
    for (kind, a) in tr.arcs() {
        let place = format!("{prefix}.{}", net.places[a.place.0].id);
        out.add_arc(kind, &place, t, a.weight)
            .expect("the place was copied");
    }
}

/// A distinct prefix per net: its id, numbered when two nets share one.
fn prefixes(nets: &[Net]) -> Vec<String> {
    let mut count: HashMap<&str, usize> = HashMap::new();
    for n in nets {
        *count.entry(n.id.as_str()).or_default() += 1;
    }
    let mut seen: HashMap<&str, usize> = HashMap::new();
    nets.iter()
        .map(|n| {
            let base = if n.id.is_empty() {
                "net"
            } else {
                n.id.as_str()
            };
            if count[n.id.as_str()] == 1 {
                base.to_owned()
            } else {
                let i = seen.entry(n.id.as_str()).or_default();
                *i += 1;
                format!("{base}{i}")
            }
        })
        .collect()
}

/// Fuses parallel places — same input and output transitions with the same
/// weights, same initial marking and capacity — into one (Murata's fusion of
/// parallel places), which preserves the net's behaviour. The fused place
/// keeps the first one's id and lists all their names.
pub fn fuse_parallel_places(net: &Net) -> Net {
    // A place's signature: its arcs to every transition, and its marking.
    let signature = |p: usize| {
        let mut arcs: Vec<(usize, ArcKind, u32)> = Vec::new();
        for (t, tr) in net.transitions.iter().enumerate() {
            for (kind, a) in tr.arcs().filter(|(_, a)| a.place.0 == p) {
                arcs.push((t, kind, a.weight));
            }
        }
        (arcs, net.places[p].initial, net.places[p].capacity)
    };
    let mut groups: Vec<(_, Vec<usize>)> = Vec::new();
    let mut index: HashMap<_, usize> = HashMap::new();
    for p in 0..net.places.len() {
        let sig = signature(p);
        match index.get(&sig) {
            Some(&g) => groups[g].1.push(p),
            None => {
                index.insert(sig.clone(), groups.len());
                groups.push((sig, vec![p]));
            }
        }
    }
    let mut out = Net::new(&net.id);
    let mut keep = vec![None; net.places.len()];
    for (_, members) in &groups {
        let first = &net.places[members[0]];
        let q = out
            .add_place(&first.id, first.initial)
            .expect("ids stay unique");
        out.places[q.0].capacity = first.capacity;
        out.places[q.0].name = members
            .iter()
            .map(|&m| net.places[m].name.as_str())
            .collect::<Vec<_>>()
            .join("|");
        keep[members[0]] = Some(first.id.clone());
    }
    for tr in &net.transitions {
        let t = out
            .add_transition(&tr.id, tr.label.as_deref())
            .expect("ids stay unique");
        out.transitions[t.0].name = tr.name.clone();
        for (kind, a) in tr.arcs() {
            if let Some(id) = &keep[a.place.0] {
                out.add_arc(kind, id, t, a.weight)
                    .expect("the kept place exists");
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn component(id: &str, label: &str) -> Net {
        let mut n = Net::new(id);
        n.add_place("idle", 1).unwrap();
        n.add_place("busy", 0).unwrap();
        n.add_transition_with("go", Some(label), &[("idle", 1)], &[("busy", 1)])
            .unwrap();
        n.add_transition_with("back", None, &[("busy", 1)], &[("idle", 1)])
            .unwrap();
        n
    }

    #[test]
    fn shared_labels_fuse() {
        let c = compose(&[component("a", "start"), component("b", "start")]).unwrap();
        let ids: Vec<&str> = c.transitions.iter().map(|t| t.id.as_str()).collect();
        assert_eq!(ids, ["a.back", "b.back", "a.go|b.go"]);
        let fused = &c.transitions[2];
        assert_eq!(fused.pre.len(), 2);
        assert_eq!(fused.post.len(), 2);
        let other = compose(&[component("a", "x"), component("b", "y")]).unwrap();
        assert_eq!(other.transitions.len(), 4, "different labels do not fuse");
    }

    #[test]
    fn parallel_places_fuse() {
        let mut n = component("a", "s");
        n.add_place("shadow", 1).unwrap();
        let go = n.transition("go").unwrap();
        let back = n.transition("back").unwrap();
        n.add_arc(ArcKind::Input, "shadow", go, 1).unwrap();
        n.add_arc(ArcKind::Output, "shadow", back, 1).unwrap();
        let fused = fuse_parallel_places(&n);
        assert_eq!(fused.places.len(), 2);
        assert_eq!(fused.places[0].name, "idle|shadow");
    }
}
