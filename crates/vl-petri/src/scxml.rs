//! UML statecharts (W3C SCXML) to Petri nets, the thesis's first step.
//!
//! One place per state — atomic, compound, parallel or final — marked while
//! the state is active, so a compound state's place is marked together with
//! those of its active descendants. One Petri transition per statechart
//! transition and per way the states it leaves can be active, labelled with
//! the event: it takes the tokens of every state the transition exits (the
//! join of a parallel state's regions) and gives tokens to every state it
//! enters (the fork into each region's initial state). Exits and entries
//! follow SCXML's rule: everything below the least common compound ancestor
//! of source and target.

use std::collections::BTreeSet;

use roxmltree::{Document, Node};
use thiserror::Error;

use crate::lines::LineStarts;
use crate::net::{ArcKind, Net};

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ScxmlError {
    #[error("not well-formed XML: {0}")]
    Xml(String),
    #[error("the root element is <{0}>, not <scxml>")]
    NotScxml(String),
    #[error("line {line}: a <{element}> has no id")]
    MissingId { element: String, line: u32 },
    #[error("line {line}: state id '{id}' is used twice")]
    DuplicateId { id: String, line: u32 },
    #[error("line {line}: transition targets unknown state '{target}'")]
    UnknownTarget { target: String, line: u32 },
    #[error("line {line}: initial state '{initial}' is not a child of '{parent}'")]
    BadInitial {
        initial: String,
        parent: String,
        line: u32,
    },
    #[error("line {line}: transitions with several targets are not supported")]
    MultipleTargets { line: u32 },
    #[error("the chart has no states")]
    Empty,
    #[error("line {line}: states nest more than {MAX_NESTING} deep")]
    TooDeep { line: u32 },
    #[error("state '{0}' can be active in more than {1} ways; the net would be too large")]
    TooManyConfigurations(String, usize),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Atomic,
    Compound,
    Parallel,
}

#[derive(Debug)]
struct State {
    id: String,
    kind: Kind,
    parent: Option<usize>,
    children: Vec<usize>,
    /// The child entered by default (compound states).
    initial: Option<usize>,
}

#[derive(Debug)]
struct ChartTransition {
    source: usize,
    target: Option<usize>,
    event: Option<String>,
}

/// Active configurations of one subtree a transition may exit.
const MAX_CONFIGURATIONS: usize = 10_000;
/// How deep states may nest: far beyond any chart a person draws, and
/// shallow enough that walking the tree cannot exhaust the stack.
const MAX_NESTING: usize = 64;

/// The Petri net of the statechart in `text`.
pub fn from_scxml(text: &str) -> Result<Net, ScxmlError> {
    let doc = Document::parse(text).map_err(|e| ScxmlError::Xml(e.to_string()))?;
    let root = doc.root_element();
    if root.tag_name().name() != "scxml" {
        return Err(ScxmlError::NotScxml(root.tag_name().name().to_owned()));
    }
    let lines = LineStarts::new(text);
    let line = |n: Node| lines.of(n.range().start);
    let mut states: Vec<State> = Vec::new();
    let mut pending: Vec<(usize, Node)> = Vec::new(); // (source state, <transition>)
    let mut initials: Vec<(Option<usize>, String, u32)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut chart = Collected {
        states: &mut states,
        seen: &mut seen,
        pending: &mut pending,
        initials: &mut initials,
    };
    collect(root, None, 0, &mut chart, &line)?;
    if states.is_empty() {
        return Err(ScxmlError::Empty);
    }
    let ids: Vec<String> = states.iter().map(|s| s.id.clone()).collect();
    let find = |id: &str| ids.iter().position(|s| s == id);
    // Explicit initial states, checked to be children of their parent.
    let top: Vec<usize> = (0..states.len())
        .filter(|&s| states[s].parent.is_none())
        .collect();
    let mut root_initial = top[0];
    for (parent, id, l) in initials {
        let s = find(&id).ok_or_else(|| ScxmlError::UnknownTarget {
            target: id.clone(),
            line: l,
        })?;
        if states[s].parent != parent {
            return Err(ScxmlError::BadInitial {
                initial: id,
                parent: parent.map_or("scxml".to_owned(), |p| states[p].id.clone()),
                line: l,
            });
        }
        match parent {
            Some(p) => states[p].initial = Some(s),
            None => root_initial = s,
        }
    }
    for state in &mut states {
        if state.kind == Kind::Compound && state.initial.is_none() {
            state.initial = state.children.first().copied();
        }
    }
    let mut transitions = Vec::new();
    for (source, node) in pending {
        let target = match node.attribute("target").map(str::split_whitespace) {
            None => None,
            Some(mut ids) => {
                let first = ids.next();
                if ids.next().is_some() {
                    return Err(ScxmlError::MultipleTargets { line: line(node) });
                }
                match first {
                    None => None,
                    Some(id) => Some(find(id).ok_or_else(|| ScxmlError::UnknownTarget {
                        target: id.to_owned(),
                        line: line(node),
                    })?),
                }
            }
        };
        let event = node
            .attribute("event")
            .map(|e| e.trim().to_owned())
            .filter(|e| !e.is_empty());
        transitions.push(ChartTransition {
            source,
            target,
            event,
        });
    }
    build(
        &states,
        root_initial,
        &transitions,
        root.attribute("name").unwrap_or("statechart"),
    )
}

/// What walking the chart's elements gathers.
struct Collected<'c, 'a, 'i> {
    states: &'c mut Vec<State>,
    /// The ids taken so far.
    seen: &'c mut std::collections::HashSet<&'a str>,
    /// (source state, `<transition>`)
    pending: &'c mut Vec<(usize, Node<'a, 'i>)>,
    initials: &'c mut Vec<(Option<usize>, String, u32)>,
}

fn collect<'a, 'i>(
    node: Node<'a, 'i>,
    parent: Option<usize>,
    depth: usize,
    chart: &mut Collected<'_, 'a, 'i>,
    line: &dyn Fn(Node) -> u32,
) -> Result<(), ScxmlError> {
    if depth > MAX_NESTING {
        return Err(ScxmlError::TooDeep { line: line(node) });
    }
    if let Some(first) = node
        .attribute("initial")
        .and_then(|i| i.split_whitespace().next())
    {
        chart.initials.push((parent, first.to_owned(), line(node)));
    }
    for child in node.children().filter(Node::is_element) {
        let tag = child.tag_name().name();
        if tag == "initial" {
            // <initial><transition target="…"/></initial>
            if let Some(t) = child
                .children()
                .find(|c| c.tag_name().name() == "transition")
                && let Some(target) = t.attribute("target")
            {
                chart
                    .initials
                    .push((parent, target.trim().to_owned(), line(t)));
            }
            continue;
        }
        if !matches!(tag, "state" | "parallel" | "final") {
            continue;
        }
        let id = child.attribute("id").ok_or_else(|| ScxmlError::MissingId {
            element: tag.to_owned(),
            line: line(child),
        })?;
        if !chart.seen.insert(id) {
            return Err(ScxmlError::DuplicateId {
                id: id.to_owned(),
                line: line(child),
            });
        }
        let has_children = child
            .children()
            .any(|c| matches!(c.tag_name().name(), "state" | "parallel" | "final"));
        let kind = match (tag, has_children) {
            ("parallel", _) => Kind::Parallel,
            ("state", true) => Kind::Compound,
            _ => Kind::Atomic,
        };
        let index = chart.states.len();
        chart.states.push(State {
            id: id.to_owned(),
            kind,
            parent,
            children: Vec::new(),
            initial: None,
        });
        if let Some(p) = parent {
            chart.states[p].children.push(index);
        }
        for t in child
            .children()
            .filter(|c| c.tag_name().name() == "transition")
        {
            chart.pending.push((index, t));
        }
        collect(child, Some(index), depth + 1, chart, line)?;
    }
    Ok(())
}

/// Ancestors of `s`, nearest first, not including `s`.
fn ancestors(states: &[State], s: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut at = states[s].parent;
    while let Some(a) = at {
        out.push(a);
        at = states[a].parent;
    }
    out
}

/// States entered by default when `s` is entered: `s`, then its initial
/// child's (compound) or every child's (parallel) default entry.
fn default_entry(states: &[State], s: usize, into: &mut BTreeSet<usize>) {
    into.insert(s);
    match states[s].kind {
        Kind::Atomic => {}
        Kind::Compound => {
            if let Some(c) = states[s].initial {
                default_entry(states, c, into);
            }
        }
        Kind::Parallel => {
            for &c in &states[s].children {
                default_entry(states, c, into);
            }
        }
    }
}

/// Every set of states that can be active inside `s` when `s` is active.
fn configurations(states: &[State], s: usize) -> Result<Vec<BTreeSet<usize>>, ScxmlError> {
    let mut out: Vec<BTreeSet<usize>> = match states[s].kind {
        Kind::Atomic => vec![BTreeSet::new()],
        Kind::Compound => {
            let mut all = Vec::new();
            for &c in &states[s].children {
                all.extend(configurations(states, c)?);
            }
            all
        }
        Kind::Parallel => {
            let mut product = vec![BTreeSet::new()];
            for &c in &states[s].children {
                let options = configurations(states, c)?;
                let mut next = Vec::new();
                for base in &product {
                    for o in &options {
                        next.push(base.union(o).copied().collect());
                    }
                }
                if next.len() > MAX_CONFIGURATIONS {
                    return Err(ScxmlError::TooManyConfigurations(
                        states[s].id.clone(),
                        MAX_CONFIGURATIONS,
                    ));
                }
                product = next;
            }
            product
        }
    };
    for set in &mut out {
        set.insert(s);
    }
    Ok(out)
}

fn build(
    states: &[State],
    root_initial: usize,
    transitions: &[ChartTransition],
    name: &str,
) -> Result<Net, ScxmlError> {
    let mut net = Net::new(name);
    let mut active = BTreeSet::new();
    default_entry(states, root_initial, &mut active);
    for (i, s) in states.iter().enumerate() {
        net.add_place(&s.id, u32::from(active.contains(&i)))
            .expect("state ids are unique");
    }
    for (n, tr) in transitions.iter().enumerate() {
        let (exit_root, entered) = match tr.target {
            // A targetless transition leaves and enters nothing: a self-loop on its source.
            None => (None, BTreeSet::from([tr.source])),
            Some(target) => {
                // The domain: the nearest compound proper ancestor of both source and
                // target (so a transition to an ancestor exits and re-enters it).
                let target_line: Vec<usize> = ancestors(states, target);
                let domain = ancestors(states, tr.source)
                    .into_iter()
                    .filter(|a| states[*a].kind == Kind::Compound)
                    .find(|a| target_line.contains(a));
                let below = |s: usize| -> usize {
                    // The ancestor-or-self of s that is a child of the domain.
                    let mut at = s;
                    while states[at].parent != domain {
                        at = states[at].parent.expect("the domain is an ancestor");
                    }
                    at
                };
                let mut entered = BTreeSet::new();
                let mut path = vec![target];
                path.extend(
                    ancestors(states, target)
                        .into_iter()
                        .take_while(|a| Some(*a) != domain),
                );
                for &s in path.iter().rev() {
                    entered.insert(s);
                    if states[s].kind == Kind::Parallel {
                        for &c in &states[s].children {
                            if !path.contains(&c) {
                                default_entry(states, c, &mut entered);
                            }
                        }
                    }
                }
                default_entry(states, target, &mut entered);
                (Some(below(tr.source)), entered)
            }
        };
        // The source must be active; each way the exited subtree can be active is one Petri transition.
        let exits: Vec<BTreeSet<usize>> = match exit_root {
            None => vec![BTreeSet::from([tr.source])],
            Some(r) => configurations(states, r)?
                .into_iter()
                .filter(|c| c.contains(&tr.source))
                .collect(),
        };
        let event = tr.event.as_deref();
        let base = format!("{}_{}", states[tr.source].id, event.unwrap_or("auto"));
        for (k, exited) in exits.iter().enumerate() {
            let id = if exits.len() == 1 {
                format!("t{}_{base}", n + 1)
            } else {
                format!("t{}_{base}_{}", n + 1, k + 1)
            };
            let t = net
                .add_transition(&id, event)
                .expect("transition ids are unique");
            for &s in exited {
                net.add_arc(ArcKind::Input, &states[s].id, t, 1)
                    .expect("state places exist");
            }
            for &s in &entered {
                net.add_arc(ArcKind::Output, &states[s].id, t, 1)
                    .expect("state places exist");
            }
        }
    }
    Ok(net)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAB: &str = r#"<scxml xmlns="http://www.w3.org/2005/07/scxml" version="1.0" initial="idle" name="lab">
  <state id="idle"><transition event="mount" target="session"/></state>
  <state id="session" initial="mounted">
    <state id="mounted"><transition event="define" target="defined"/></state>
    <state id="defined"><transition event="start" target="running"/></state>
    <parallel id="running">
      <state id="robot" initial="moving">
        <state id="moving"><transition event="arrive" target="stopped"/></state>
        <state id="stopped"/>
      </state>
      <state id="camera"><state id="streaming"/></state>
    </parallel>
    <transition event="release" target="idle"/>
  </state>
  <final id="off"/>
</scxml>"#;

    #[test]
    fn states_become_places_and_parallel_regions_fork() {
        let net = from_scxml(LAB).unwrap();
        let marked: Vec<&str> = net
            .places
            .iter()
            .filter(|p| p.initial == 1)
            .map(|p| p.id.as_str())
            .collect();
        assert_eq!(marked, ["idle"]);
        let start = net
            .transitions
            .iter()
            .find(|t| t.label.as_deref() == Some("start"))
            .unwrap();
        let gives: BTreeSet<&str> = start
            .post
            .iter()
            .map(|a| net.places[a.place.0].id.as_str())
            .collect();
        assert_eq!(
            gives,
            BTreeSet::from(["running", "robot", "moving", "camera", "streaming"])
        );
        // "release" leaves session however it is active: one Petri transition per configuration.
        let releases = net
            .transitions
            .iter()
            .filter(|t| t.label.as_deref() == Some("release"))
            .count();
        assert_eq!(
            releases, 4,
            "mounted, defined, running/moving, running/stopped"
        );
    }

    #[test]
    fn bad_charts_are_named() {
        assert!(matches!(
            from_scxml("<scxml><state"),
            Err(ScxmlError::Xml(_))
        ));
        assert_eq!(
            from_scxml("<chart/>"),
            Err(ScxmlError::NotScxml("chart".into()))
        );
        let bad_target = LAB.replace(r#"target="stopped""#, r#"target="nowhere""#);
        assert!(matches!(
            from_scxml(&bad_target),
            Err(ScxmlError::UnknownTarget { line: 8, .. })
        ));
        let twice = LAB.replace(r#"<final id="off"/>"#, r#"<final id="idle"/>"#);
        assert!(matches!(
            from_scxml(&twice),
            Err(ScxmlError::DuplicateId { .. })
        ));
    }
}
