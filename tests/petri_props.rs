//! Property tests of vl-petri on random small nets, with and without
//! inhibitor arcs and capacities: the explorer agrees with a naive one built
//! on the plain firing rule, PNML export → import is the identity, and the
//! analysis's deadlock trace really leads to a dead marking.

use std::collections::{HashSet, VecDeque};

use proptest::prelude::*;
use vl_petri::{ArcKind, Marking, Net, Options, analyze, explore, from_pnml, to_pnml};

/// A random net: 1–5 places, 1–5 transitions, weights 1–3.
fn net() -> impl Strategy<Value = Net> {
    (1usize..=5, 1usize..=5).prop_flat_map(|(places, transitions)| {
        let arc = (0..places, 1u32..=3, 0u8..10);
        (
            proptest::collection::vec(0u32..=2, places),
            proptest::collection::vec(proptest::option::weighted(0.2, 1u32..=3), places),
            proptest::collection::vec(proptest::collection::vec(arc, 0..5), transitions),
            proptest::collection::vec(proptest::option::of("[a-c]"), transitions),
        )
            .prop_map(move |(initial, capacities, arcs, labels)| {
                let mut net = Net::new("random");
                for (i, (&m, &cap)) in initial.iter().zip(&capacities).enumerate() {
                    let p = net.add_place(&format!("p{i}"), m).unwrap();
                    // A capacity below the initial marking would make m0 itself illegal.
                    net.places[p.0].capacity = cap.map(|c| c.max(m));
                }
                for (t, (arcs, label)) in arcs.iter().zip(&labels).enumerate() {
                    let id = net.add_transition(&format!("t{t}"), label.as_deref()).unwrap();
                    for &(p, w, kind) in arcs {
                        let kind = match kind {
                            0..=4 => ArcKind::Input,
                            5..=8 => ArcKind::Output,
                            _ => ArcKind::Inhibitor,
                        };
                        net.add_arc(kind, &format!("p{p}"), id, w).unwrap();
                    }
                }
                net
            })
    })
}

const LIMIT: usize = 3000;

/// Breadth-first search with the net's own firing rule: the reference.
fn naive(net: &Net) -> Option<(HashSet<Marking>, usize)> {
    let m0 = net.initial_marking();
    let mut seen = HashSet::from([m0.clone()]);
    let mut queue = VecDeque::from([m0]);
    let mut edges = 0;
    while let Some(m) = queue.pop_front() {
        for t in net.enabled(&m).collect::<Vec<_>>() {
            let next = net.fire(&m, t).ok()?;
            edges += 1;
            if seen.insert(next.clone()) {
                if seen.len() > LIMIT {
                    return None;
                }
                queue.push_back(next);
            }
        }
    }
    Some((seen, edges))
}

/// The fewest firings from m0 to a dead marking, by plain BFS.
fn distance_to_deadlock(net: &Net) -> usize {
    let m0 = net.initial_marking();
    let mut seen = HashSet::from([m0.clone()]);
    let mut queue = VecDeque::from([(m0, 0)]);
    while let Some((m, d)) = queue.pop_front() {
        let enabled: Vec<_> = net.enabled(&m).collect();
        if enabled.is_empty() {
            return d;
        }
        for t in enabled {
            let next = net.fire(&m, t).unwrap();
            if seen.insert(next.clone()) {
                queue.push_back((next, d + 1));
            }
        }
    }
    usize::MAX
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn the_explorer_agrees_with_the_firing_rule(net in net()) {
        let reference = naive(&net);
        let explored = explore(&net, Options { max_states: LIMIT, progress: None });
        match (reference, explored) {
            (Some((markings, edges)), Ok(space)) => {
                let found: HashSet<Marking> = (0..space.states()).map(|s| space.marking(s)).collect();
                prop_assert_eq!(space.states(), found.len(), "no marking is stored twice");
                prop_assert_eq!(found, markings);
                prop_assert_eq!(space.edges(), edges);
            }
            (None, Err(_)) => {} // too large for both
            (reference, explored) => prop_assert!(false, "naive {:?} vs explorer {:?}", reference.map(|r| r.0.len()), explored.map(|s| s.states())),
        }
    }

    #[test]
    fn pnml_export_then_import_is_the_identity(net in net()) {
        prop_assert_eq!(from_pnml(&to_pnml(&net)).unwrap(), net);
    }

    #[test]
    fn a_deadlock_trace_reaches_a_dead_marking(net in net()) {
        let Ok(space) = explore(&net, Options { max_states: LIMIT, progress: None }) else {
            return Ok(());
        };
        let a = analyze(&net, &space);
        prop_assert_eq!(a.deadlock, a.deadlock_trace.is_some());
        if let Some(trace) = a.deadlock_trace {
            let mut m = net.initial_marking();
            for id in &trace {
                m = net.fire(&m, net.transition(id).unwrap()).unwrap();
            }
            prop_assert_eq!(net.enabled(&m).count(), 0, "the trace ends in a dead marking");
            prop_assert_eq!(trace.len(), distance_to_deadlock(&net), "and is a shortest one");
        }
        // Safe and bounds agree with the explored markings.
        let max = (0..space.states()).flat_map(|s| space.marking(s).0).max().unwrap_or(0);
        prop_assert_eq!(a.max_tokens_in_place, max);
        prop_assert_eq!(a.safe, max <= 1);
    }
}
