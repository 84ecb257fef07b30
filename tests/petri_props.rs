//! Property tests of vl-petri on random small nets, with and without
//! inhibitor arcs and capacities: the explorer agrees with a naive one built
//! on the plain firing rule, PNML export → import is the identity, and the
//! analysis's deadlock trace really leads to a dead marking.

use std::collections::{HashSet, VecDeque};

use proptest::prelude::*;
use vl_petri::{
    Analysis, ArcKind, Constraint, Limits, Liveness, Marking, Net, OMEGA, Options, analyze,
    analyze_net, compose, count_states, coverability, explore, from_pnml, fuse_parallel_places,
    no_way_back, p_invariants, synthesize, t_invariants, to_pnml,
};

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
                    let id = net
                        .add_transition(&format!("t{t}"), label.as_deref())
                        .unwrap();
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

/// Nets of processes: rings of 2–6 places holding one token each (a
/// process's local states: the one-hot groups the explorer packs into one
/// field each), steps within a ring, steps of two rings at once, and a
/// shared place some of those take a token from and others give one to.
fn processes() -> impl Strategy<Value = Net> {
    let sync = (0usize..3, 0usize..6, 0usize..3, 0usize..6, 0u8..4);
    (
        proptest::collection::vec(2usize..=6, 1..=3),
        0u32..=2,
        proptest::collection::vec(sync, 0..6),
    )
        .prop_map(|(rings, shared, syncs)| {
            let mut net = Net::new("processes");
            let place = |r: usize, i: usize| format!("r{r}_{i}");
            for (r, &n) in rings.iter().enumerate() {
                for i in 0..n {
                    net.add_place(&place(r, i), u32::from(i == 0)).unwrap();
                }
            }
            net.add_place("shared", shared).unwrap();
            let mut add = |id: String, pre: Vec<(String, u32)>, post: Vec<(String, u32)>| {
                let pre: Vec<(&str, u32)> = pre.iter().map(|(p, w)| (p.as_str(), *w)).collect();
                let post: Vec<(&str, u32)> = post.iter().map(|(p, w)| (p.as_str(), *w)).collect();
                net.add_transition_with(&id, None, &pre, &post).unwrap();
            };
            for (r, &n) in rings.iter().enumerate() {
                for i in 0..n {
                    add(
                        format!("step{r}_{i}"),
                        vec![(place(r, i), 1)],
                        vec![(place(r, (i + 1) % n), 1)],
                    );
                }
            }
            for (k, &(a, i, b, j, uses)) in syncs.iter().enumerate() {
                let (a, b) = (a % rings.len(), b % rings.len());
                if a == b {
                    continue;
                }
                let (i, j) = (i % rings[a], j % rings[b]);
                let mut pre = vec![(place(a, i), 1), (place(b, j), 1)];
                let mut post = vec![
                    (place(a, (i + 1) % rings[a]), 1),
                    (place(b, (j + 1) % rings[b]), 1),
                ];
                match uses {
                    0 => pre.push(("shared".into(), 1)),
                    1 => post.push(("shared".into(), 1)),
                    _ => {}
                }
                add(format!("sync{k}"), pre, post);
            }
            net
        })
}

/// The reachability graph, if it has at most LIMIT states.
fn small(net: &Net) -> Option<vl_petri::StateSpace> {
    explore(
        net,
        Options {
            max_states: LIMIT,
            progress: None,
            deadline: None,
        },
    )
    .ok()
}

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
        let explored = explore(&net, Options { max_states: LIMIT, progress: None, deadline: None });
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

    /// Processes' local states packed one field per process still give
    /// exactly the markings, firings and bounds of the firing rule.
    #[test]
    fn one_hot_packing_agrees_with_the_firing_rule(net in processes()) {
        let reference = naive(&net);
        let explored = explore(&net, Options { max_states: LIMIT, progress: None, deadline: None });
        let counted = count_states(&net, Options { max_states: LIMIT, progress: None, deadline: None }, 2);
        match (reference, explored, counted) {
            (Some((markings, edges)), Ok(space), Ok(count)) => {
                let found: HashSet<Marking> = (0..space.states()).map(|s| space.marking(s)).collect();
                prop_assert_eq!(space.states(), found.len(), "no marking is stored twice");
                prop_assert_eq!(&found, &markings);
                prop_assert_eq!(space.edges(), edges);
                prop_assert_eq!(count.states, markings.len());
                prop_assert_eq!(count.edges, edges);
            }
            (None, Err(_), Err(_)) => {}
            (reference, explored, _) => prop_assert!(false, "naive {:?} vs explorer {:?}", reference.map(|r| r.0.len()), explored.map(|s| s.states())),
        }
    }

    /// Liveness levels and reversibility as their definitions say, by
    /// brute force over every pair of markings of a small graph.
    #[test]
    fn liveness_and_reversibility_follow_their_definitions(net in prop_oneof![net(), processes()]) {
        let Some((markings, _)) = naive(&net) else { return Ok(()) };
        prop_assume!(markings.len() <= 200);
        let markings: Vec<Marking> = markings.into_iter().collect();
        let id = |m: &Marking| markings.iter().position(|x| x == m).unwrap();
        let edges: Vec<Vec<(usize, usize)>> = markings
            .iter()
            .map(|m| {
                net.enabled(m)
                    .collect::<Vec<_>>()
                    .into_iter()
                    .map(|t| (t.0, id(&net.fire(m, t).unwrap())))
                    .collect()
            })
            .collect();
        // reach[a][b]: b is reachable from a (in zero or more firings).
        let reach: Vec<Vec<bool>> = (0..markings.len())
            .map(|a| {
                let mut seen = vec![false; markings.len()];
                let mut queue = VecDeque::from([a]);
                seen[a] = true;
                while let Some(x) = queue.pop_front() {
                    for &(_, y) in &edges[x] {
                        if !seen[y] {
                            seen[y] = true;
                            queue.push_back(y);
                        }
                    }
                }
                seen
            })
            .collect();
        let m0 = id(&net.initial_marking());
        let a = analyze(&net, &explore(&net, Options::default()).unwrap());
        let on_the_fly = analyze_net(&net, Options::default()).unwrap();
        prop_assert_eq!(&Analysis { bytes_per_marking: a.bytes_per_marking, ..on_the_fly }, &a);
        prop_assert_eq!(a.reversible, (0..markings.len()).all(|x| reach[x][m0]));
        // The state shown for no way back cannot reach the start; there is
        // one exactly when the net is not reversible.
        let space = explore(&net, Options::default()).unwrap();
        match no_way_back(&space) {
            Some(s) => {
                let stuck = id(&space.marking(s));
                prop_assert!(!reach[stuck][m0] && !a.reversible);
            }
            None => prop_assert!(a.reversible),
        }
        for t in 0..net.transitions.len() {
            let fires_at = |x: usize| edges[x].iter().any(|&(u, _)| u == t);
            let l4 = (0..markings.len()).all(|x| (0..markings.len()).any(|y| reach[x][y] && fires_at(y)));
            let l3 = (0..markings.len()).any(|x| edges[x].iter().any(|&(u, y)| u == t && reach[y][x]));
            let l1 = (0..markings.len()).any(fires_at);
            let want = if l4 { Liveness::L4 } else if l3 { Liveness::L3 } else if l1 { Liveness::L1 } else { Liveness::L0 };
            prop_assert_eq!(a.liveness[t], want, "transition {}", t);
        }
    }

    /// Counting without the graph, on one thread or several, finds the
    /// same states, firings and bounds.
    #[test]
    fn counting_states_agrees_with_the_firing_rule(net in net(), threads in 1usize..=3) {
        let reference = naive(&net);
        let counted = count_states(&net, Options { max_states: LIMIT, progress: None, deadline: None }, threads);
        match (reference, counted) {
            (Some((markings, edges)), Ok(count)) => {
                prop_assert_eq!(count.states, markings.len());
                prop_assert_eq!(count.edges, edges);
                let bounds: Vec<u32> = (0..net.places.len())
                    .map(|p| markings.iter().map(|m| m.0[p]).max().unwrap_or(0))
                    .collect();
                prop_assert_eq!(count.bounds.places, bounds);
                let most = markings.iter().map(|m| m.0.iter().map(|&v| u64::from(v)).sum::<u64>()).max();
                prop_assert_eq!(Some(count.bounds.per_marking), most);
            }
            (None, Err(_)) => {}
            (reference, counted) => prop_assert!(false, "naive {:?} vs counted {:?}", reference.map(|r| r.0.len()), counted.map(|c| c.states)),
        }
    }

    #[test]
    fn pnml_export_then_import_is_the_identity(net in net()) {
        prop_assert_eq!(from_pnml(&to_pnml(&net)).unwrap(), net);
    }

    /// Tarjan inside the depth-first search reads what the stored graph
    /// says, and stops where it does.
    #[test]
    fn analysis_on_the_fly_agrees_with_the_stored_graph(net in prop_oneof![net(), processes()]) {
        let limit = || Options { max_states: LIMIT, progress: None, deadline: None };
        match (explore(&net, limit()), analyze_net(&net, limit())) {
            (Ok(space), Ok(on_the_fly)) => {
                let a = analyze(&net, &space);
                prop_assert_eq!(Analysis { bytes_per_marking: a.bytes_per_marking, ..on_the_fly }, a);
            }
            (Err(stored), Err(on_the_fly)) => prop_assert_eq!(stored, on_the_fly),
            (stored, on_the_fly) => prop_assert!(false, "stored {:?}, on the fly {:?}", stored.map(|s| s.states()), on_the_fly.map(|a| a.states)),
        }
    }

    #[test]
    fn a_deadlock_trace_reaches_a_dead_marking(net in net()) {
        let Ok(space) = explore(&net, Options { max_states: LIMIT, progress: None, deadline: None }) else {
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

/// The same random nets without inhibitor arcs or capacities (monotone nets,
/// where Karp–Miller is sound).
fn monotone_net() -> impl Strategy<Value = Net> {
    net().prop_map(|mut n| {
        n.places.iter_mut().for_each(|p| p.capacity = None);
        n.transitions.iter_mut().for_each(|t| t.inhibit.clear());
        n
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn karp_miller_covers_every_reachable_marking(net in monotone_net()) {
        let c = coverability(&net, 20_000).unwrap();
        let maximal = c.maximal();
        // Every marking explored (all of them when bounded, the first few
        // thousand otherwise) is covered by a maximal ω-marking.
        let space = explore(&net, Options { max_states: LIMIT, progress: None, deadline: None });
        let markings: Vec<Marking> = match &space {
            Ok(space) => (0..space.states()).map(|s| space.marking(s)).collect(),
            Err(_) => naive_prefix(&net),
        };
        for m in &markings {
            prop_assert!(
                maximal.iter().any(|k| k.iter().zip(&m.0).all(|(a, b)| a >= b)),
                "{:?} is not covered", m
            );
        }
        // An unbounded net cannot be explored to the end; a bounded one has no ω.
        if !c.bounded() {
            prop_assert!(space.is_err());
        } else {
            prop_assert!(maximal.iter().all(|k| k.iter().all(|&v| v != OMEGA)));
        }
    }

    #[test]
    fn invariants_are_invariant(net in monotone_net()) {
        let c = net.incidence();
        let p = p_invariants(&net, 10_000).unwrap();
        for y in &p {
            let y_c: Vec<i64> = (0..net.transitions.len())
                .map(|t| y.iter().map(|&(i, k)| k as i64 * c[i][t]).sum())
                .collect();
            prop_assert!(y_c.iter().all(|&v| v == 0), "yᵀC = {:?} for {:?}", y_c, y);
        }
        for x in &t_invariants(&net, 10_000).unwrap() {
            for row in &c {
                let dot: i64 = x.iter().map(|&(j, k)| k as i64 * row[j]).sum();
                prop_assert_eq!(dot, 0, "Cx ≠ 0 for {:?}", x);
            }
        }
        // Minimal supports: none contains another.
        for (i, a) in p.iter().enumerate() {
            for (j, b) in p.iter().enumerate() {
                if i != j {
                    prop_assert!(!a.iter().all(|(pa, _)| b.iter().any(|(pb, _)| pa == pb)));
                }
            }
        }
        // A P-invariant's weighted token count is the same in every reachable marking.
        if let Ok(space) = explore(&net, Options { max_states: LIMIT, progress: None, deadline: None }) {
            for y in &p {
                let count = |m: &Marking| y.iter().map(|&(i, k)| k * u64::from(m.0[i])).sum::<u64>();
                let m0 = count(&net.initial_marking());
                prop_assert!((0..space.states()).all(|s| count(&space.marking(s)) == m0));
            }
        }
    }
}

/// The first LIMIT markings reached by plain BFS.
fn naive_prefix(net: &Net) -> Vec<Marking> {
    let m0 = net.initial_marking();
    let mut seen = vec![m0.clone()];
    let mut known = HashSet::from([m0.clone()]);
    let mut queue = VecDeque::from([m0]);
    while let Some(m) = queue.pop_front() {
        for t in net.enabled(&m).collect::<Vec<_>>() {
            let next = net.fire(&m, t).unwrap();
            if known.insert(next.clone()) {
                seen.push(next.clone());
                if seen.len() >= LIMIT {
                    return seen;
                }
                queue.push_back(next);
            }
        }
    }
    seen
}

/// A linear constraint over `net` that its initial marking satisfies.
fn constraint_for(net: &Net, coefficients: &[i64], slack: i64) -> (Vec<i64>, Constraint) {
    let l: Vec<i64> = (0..net.places.len())
        .map(|p| coefficients[p % coefficients.len()])
        .collect();
    let value: i64 = l
        .iter()
        .zip(&net.places)
        .map(|(k, p)| k * i64::from(p.initial))
        .sum();
    let terms = l
        .iter()
        .enumerate()
        .filter(|(_, k)| **k != 0)
        .map(|(p, &k)| (net.places[p].id.clone(), k))
        .collect();
    (
        l,
        Constraint::Linear {
            terms,
            bound: value + slack,
        },
    )
}

fn satisfies(l: &[i64], bound: i64, m: &[u32]) -> bool {
    l.iter().zip(m).map(|(k, &v)| k * i64::from(v)).sum::<i64>() <= bound
}

/// Plant markings reachable without ever leaving the constraint (plain BFS).
fn reachable_within(net: &Net, l: &[i64], bound: i64) -> Option<HashSet<Vec<u32>>> {
    let m0 = net.initial_marking();
    let mut seen = HashSet::from([m0.0.clone()]);
    let mut queue = VecDeque::from([m0]);
    while let Some(m) = queue.pop_front() {
        for t in net.enabled(&m).collect::<Vec<_>>() {
            let next = net.fire(&m, t).ok()?;
            if satisfies(l, bound, &next.0) && seen.insert(next.0.clone()) {
                if seen.len() > LIMIT {
                    return None;
                }
                queue.push_back(next);
            }
        }
    }
    Some(seen)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn a_linear_controller_is_exact_when_everything_is_controllable(
        net in net(),
        coefficients in proptest::collection::vec(-1i64..=2, 1..5),
        slack in 0i64..3,
    ) {
        let (l, constraint) = constraint_for(&net, &coefficients, slack);
        let Constraint::Linear { bound, .. } = constraint else { unreachable!() };
        let (controlled, _) = synthesize(&net, &[constraint], &Limits::default()).unwrap();
        let Ok(space) = explore(&controlled, Options { max_states: LIMIT, progress: None, deadline: None }) else {
            return Ok(());
        };
        let Some(expected) = reachable_within(&net, &l, bound) else { return Ok(()) };
        let plant_places = net.places.len();
        let mut got = HashSet::new();
        for s in 0..space.states() {
            let m = space.marking(s).0;
            prop_assert!(satisfies(&l, bound, &m[..plant_places]), "{:?} breaks the constraint", m);
            // The monitor holds exactly the slack.
            let slack_now = bound - l.iter().zip(&m).map(|(k, &v)| k * i64::from(v)).sum::<i64>();
            prop_assert_eq!(i64::from(m[plant_places]), slack_now);
            got.insert(m[..plant_places].to_vec());
        }
        prop_assert_eq!(got, expected, "maximally permissive: exactly the markings reachable inside the constraint");
    }

    #[test]
    fn with_uncontrollable_transitions_the_constraint_still_holds(
        net in monotone_net(),
        coefficients in proptest::collection::vec(0i64..=2, 1..5),
        slack in 0i64..3,
        uncontrollable in proptest::collection::vec(any::<bool>(), 5),
    ) {
        let (l, constraint) = constraint_for(&net, &coefficients, slack);
        let Constraint::Linear { bound, .. } = constraint else { unreachable!() };
        let limits = Limits {
            uncontrollable: net.transitions.iter().zip(&uncontrollable).filter(|(_, u)| **u).map(|(t, _)| t.id.clone()).collect(),
            ..Limits::default()
        };
        // Refusal is a valid answer; a controller, when given, must be right.
        let Ok((controlled, _)) = synthesize(&net, &[constraint], &limits) else { return Ok(()) };
        let Ok(space) = explore(&controlled, Options { max_states: LIMIT, progress: None, deadline: None }) else {
            return Ok(());
        };
        let plant_places = net.places.len();
        for s in 0..space.states() {
            let m = space.marking(s);
            prop_assert!(satisfies(&l, bound, &m.0[..plant_places]));
            // An uncontrollable transition the plant allows is never blocked by the controller.
            let plant_m = Marking(m.0[..plant_places].to_vec());
            for id in &limits.uncontrollable {
                let t = net.transition(id).unwrap();
                if net.is_enabled(&plant_m, t) {
                    prop_assert!(controlled.is_enabled(&m, t), "{} was disabled", id);
                }
            }
        }
    }

    #[test]
    fn an_if_then_controller_never_fires_t_while_p_is_marked(
        net in net(),
        p in 0usize..5,
        t in 0usize..5,
    ) {
        let place = net.places[p % net.places.len()].id.clone();
        let transition = net.transitions[t % net.transitions.len()].id.clone();
        let rule = Constraint::IfThenNot { place: place.clone(), transition: transition.clone() };
        let (controlled, _) = synthesize(&net, &[rule], &Limits::default()).unwrap();
        let Ok(space) = explore(&controlled, Options { max_states: LIMIT, progress: None, deadline: None }) else {
            return Ok(());
        };
        let (pi, ti) = (controlled.place(&place).unwrap(), controlled.transition(&transition).unwrap());
        for s in 0..space.states() {
            for (fired, _) in space.successors(s) {
                if fired == ti.0 {
                    prop_assert_eq!(space.marking(s).tokens(pi), 0, "{} fired while {} was marked", transition, place);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Each component, seen through the composed net, only does what it
    /// could do alone; nets with no label in common run side by side.
    #[test]
    fn composition_projects_onto_its_components(a in net(), b in net()) {
        let (mut a, mut b) = (a, b);
        a.id = "a".into();
        b.id = "b".into();
        let composed = compose(&[a.clone(), b.clone()]).unwrap();
        let (Some(sa), Some(sb), Some(sc)) = (small(&a), small(&b), small(&composed)) else {
            return Ok(());
        };
        let alone = |s: &vl_petri::StateSpace| (0..s.states()).map(|i| s.marking(i).0).collect::<HashSet<_>>();
        let (ra, rb) = (alone(&sa), alone(&sb));
        let na = a.places.len();
        for s in 0..sc.states() {
            let m = sc.marking(s).0;
            prop_assert!(ra.contains(&m[..na]));
            prop_assert!(rb.contains(&m[na..]));
        }
        let labels = |n: &Net| n.transitions.iter().filter_map(|t| t.label.clone()).collect::<HashSet<_>>();
        if labels(&a).is_disjoint(&labels(&b)) {
            prop_assert_eq!(sc.states(), sa.states() * sb.states());
        }
        // Fusing parallel places never changes what can happen.
        let fused = fuse_parallel_places(&composed);
        if let Some(sf) = small(&fused) {
            prop_assert_eq!(sf.states(), sc.states());
            prop_assert_eq!(sf.edges(), sc.edges());
        }
    }
}

/// A cycle the net can leave for good, for another it never leaves: the
/// first's transitions are L3 (they fire again and again, but not once it
/// is left), the way out L1, the second's L4.
#[test]
fn a_cycle_left_for_another_is_l3() {
    let mut net = Net::new("leave");
    for (p, m) in [("here", 1), ("there", 0), ("a", 0), ("b", 0)] {
        net.add_place(p, m).unwrap();
    }
    for (t, from, to) in [
        ("go", "here", "there"),
        ("back", "there", "here"),
        ("leave", "here", "a"),
        ("spin", "a", "b"),
        ("spin_back", "b", "a"),
    ] {
        net.add_transition_with(t, None, &[(from, 1)], &[(to, 1)])
            .unwrap();
    }
    let a = analyze(&net, &explore(&net, Options::default()).unwrap());
    use Liveness::*;
    assert_eq!(a.liveness, [L3, L3, L1, L4, L4]);
    assert!(!a.reversible && !a.deadlock && !a.live);
}

/// A token round a ring of n places, with a dead end off each: the
/// depth-first search runs the ring to its end, finds the edge back, and only
/// then turns into the dead ends, whose new states make the on-the-fly
/// table grow while the whole ring is open and knows it reaches its start.
/// For every n up to 110 (so each of the first growths falls in that window
/// for some n),
/// the analysis equals the stored graph's: one ring component, L3 moves
/// round it, L1 exits, a deadlock.
#[test]
fn rings_analysed_on_the_fly_as_on_their_stored_graphs() {
    for n in 2..=110 {
        let mut net = Net::new("ring");
        for k in 0..n {
            net.add_place(&format!("p{k}"), u32::from(k == 0)).unwrap();
            net.add_place(&format!("end{k}"), 0).unwrap();
        }
        for k in 0..n {
            let next = format!("p{}", (k + 1) % n);
            net.add_transition_with(
                &format!("move{k}"),
                None,
                &[(&format!("p{k}"), 1)],
                &[(&next, 1)],
            )
            .unwrap();
        }
        for k in 0..n {
            net.add_transition_with(
                &format!("exit{k}"),
                None,
                &[(&format!("p{k}"), 1)],
                &[(&format!("end{k}"), 1)],
            )
            .unwrap();
        }
        let stored = analyze(&net, &explore(&net, Options::default()).unwrap());
        let on_the_fly = analyze_net(&net, Options::default()).unwrap();
        assert_eq!(stored.states, 2 * n);
        assert!(stored.liveness[..n].iter().all(|&l| l == Liveness::L3));
        assert_eq!(
            Analysis {
                bytes_per_marking: stored.bytes_per_marking,
                ..on_the_fly
            },
            stored,
            "a ring of {n}"
        );
    }
}
