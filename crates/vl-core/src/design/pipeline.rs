//! From a lab's charts to its controlled net: from-scxml → analyse each →
//! compose → analyse the uncontrolled composition and find each rule's bad
//! interleaving → synthesise the controllers → analyse the controlled net
//! and check no rule can be broken → fuse parallel places.

use std::time::{Duration, Instant};

use vl_petri::{
    Added, Analysis, Constraint, ExploreError, Limits, Liveness, Net, Options, StateSpace, analyze,
    compose, explore, firing_sequence, from_scxml, fuse_parallel_places, no_way_back, synthesize,
};

use super::{DesignError, LabDesign, NEVER_FORBIDDEN, Rule};
use crate::{Experiment, RunComponent};

/// Reachable markings a lab's net may have before exploring gives up: the
/// labs' nets have a few dozen.
const MAX_STATES: usize = 1_000_000;
/// The longest a design's verification may take: a lab whose nets take
/// longer is refused rather than kept waiting for.
pub(crate) const VERIFY_WITHIN: Duration = Duration::from_secs(10);

/// A firing sequence that breaks a rule.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Interleaving {
    /// The events, in order; the last breaks the rule (or reaches the
    /// marking that does).
    pub events: Vec<String>,
}

/// A firing sequence after which the session can never come back to
/// where it started.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stuck {
    pub after: Interleaving,
    /// Whether nothing at all can happen then.
    pub dead_end: bool,
}

/// Everything the pipeline made of one lab's design.
#[derive(Debug, Clone)]
pub struct Designed {
    pub design: LabDesign,
    /// Each chart's net and its analysis.
    pub charts: Vec<(Net, Analysis)>,
    /// The composition, with the combinations that can never fire left out.
    pub uncontrolled: Net,
    pub uncontrolled_analysis: Analysis,
    /// Fused combinations of the composition that can never fire.
    pub never_fire: usize,
    /// For each rule, a firing sequence of the uncontrolled net that breaks it.
    pub bad: Vec<(Rule, Option<Interleaving>)>,
    /// What synthesis added for each rule.
    pub added: Vec<(Rule, Vec<Added>)>,
    /// Transitions the controllers disable for good, left out.
    pub disabled: usize,
    /// For each rule, a firing sequence of the controlled net that breaks
    /// it: none, if the controllers work.
    pub still_bad: Vec<(Rule, Option<Interleaving>)>,
    /// How the controlled net gets stuck, if it can.
    pub stuck: Option<Stuck>,
    /// The controlled net, parallel places fused: what the Host runs.
    pub controlled: Net,
    pub controlled_analysis: Analysis,
}

/// Runs the whole pipeline on one lab's design.
pub fn design(design: &LabDesign) -> Result<Designed, DesignError> {
    let deadline = Instant::now() + VERIFY_WITHIN;
    // Messages name where the design came from; nets are named by its id.
    let lab = design.source.clone();
    let charts = design
        .charts
        .iter()
        .map(|(name, text)| {
            let chart_error = |why: String| DesignError::Chart {
                lab: lab.clone(),
                chart: name.clone(),
                why,
            };
            let mut net = from_scxml(text).map_err(|e| chart_error(e.to_string()))?;
            net.id = name.clone();
            if let Some(&people) = design.people.get(name) {
                for p in net.places.iter_mut().filter(|p| p.initial > 0) {
                    p.initial = people;
                }
            }
            let (_, analysis) = analysed(&net, &lab, "chart's", deadline)?;
            Ok((net, analysis))
        })
        .collect::<Result<Vec<_>, DesignError>>()?;
    let nets: Vec<Net> = charts.iter().map(|(n, _)| n.clone()).collect();
    let mut composed = compose(&nets).map_err(|e| DesignError::Compose {
        lab: lab.clone(),
        why: e.to_string(),
    })?;
    composed.id = format!("{}-uncontrolled", design.lab);
    events_known(design, &lab, &composed)?;
    for t in &mut composed.transitions {
        t.name = t.label.clone().unwrap_or_else(|| t.id.clone());
    }
    let (space, analysis) = analysed(&composed, &lab, "uncontrolled", deadline)?;
    let (uncontrolled, never_fire) = without_dead(&composed, &analysis);
    let (space, uncontrolled_analysis) = if never_fire > 0 {
        analysed(&uncontrolled, &lab, "uncontrolled", deadline)?
    } else {
        (space, analysis)
    };
    let constraints = design
        .controllers
        .iter()
        .map(|rule| {
            expand(&uncontrolled, &rule.rule).map_err(|why| DesignError::Controller {
                lab: lab.clone(),
                rule: rule.rule.clone(),
                why,
            })
        })
        .collect::<Result<Vec<_>, DesignError>>()?;
    let bad = breaks(&uncontrolled, &space, design, &constraints);
    let limits = Limits {
        uncontrollable: design
            .uncontrollable
            .iter()
            .flat_map(|event| labelled(&uncontrolled, event))
            .collect(),
        unobservable: Vec::new(),
    };
    let flat: Vec<Constraint> = constraints.iter().flatten().cloned().collect();
    let (mut synthesised, added) =
        synthesize(&uncontrolled, &flat, &limits).map_err(|e| DesignError::Controller {
            lab: lab.clone(),
            rule: "(all)".to_owned(),
            why: e.to_string(),
        })?;
    synthesised.id = format!("{}-controlled", design.lab);
    let added = per_rule(&mut synthesised, design, &constraints, added);
    let (_, analysis) = analysed(&synthesised, &lab, "controlled", deadline)?;
    let (checked, disabled) = without_dead(&synthesised, &analysis);
    let (space, _) = analysed(&checked, &lab, "controlled", deadline)?;
    let still_bad = breaks(&checked, &space, design, &constraints);
    let stuck = no_way_back(&space).map(|s| Stuck {
        after: events(&checked, &firing_sequence(&space, s)),
        dead_end: space.successors(s).next().is_none(),
    });
    let controlled = fuse_parallel_places(&checked);
    let (_, controlled_analysis) = analysed(&controlled, &lab, "controlled", deadline)?;
    Ok(Designed {
        design: design.clone(),
        charts,
        uncontrolled,
        uncontrolled_analysis,
        never_fire,
        bad,
        added,
        disabled,
        still_bad,
        stuck,
        controlled,
        controlled_analysis,
    })
}

fn analysed(
    net: &Net,
    lab: &str,
    which: &'static str,
    deadline: Instant,
) -> Result<(StateSpace, Analysis), DesignError> {
    let space = explore(
        net,
        Options {
            max_states: MAX_STATES,
            progress: None,
            deadline: Some(deadline),
        },
    )
    .map_err(|e| DesignError::Explore {
        lab: lab.to_owned(),
        which,
        why: match e {
            ExploreError::OutOfTime => format!(
                "its state space is too large to verify in {} s",
                VERIFY_WITHIN.as_secs()
            ),
            ExploreError::TooManyStates { limit } => {
                format!("its state space is too large to verify: more than {limit} markings")
            }
            other => other.to_string(),
        },
    })?;
    let analysis = analyze(net, &space);
    Ok((space, analysis))
}

/// `net` without the transitions that never fire, and how many there were.
/// Leaving them out changes no reachable behaviour.
fn without_dead(net: &Net, analysis: &Analysis) -> (Net, usize) {
    let mut kept = net.clone();
    let mut live = analysis.liveness.iter();
    kept.transitions
        .retain(|_| live.next().is_some_and(|&l| l != Liveness::L0));
    let dropped = net.transitions.len() - kept.transitions.len();
    (kept, dropped)
}

/// The ids of the transitions labelled `event`; with `event@place`, those
/// of them that take from `place`.
fn labelled(net: &Net, event: &str) -> Vec<String> {
    let (event, from) = match event.split_once('@') {
        Some((event, place)) => match net.place(place) {
            Some(p) => (event, Some(p)),
            None => return Vec::new(),
        },
        None => (event, None),
    };
    net.transitions
        .iter()
        .filter(|t| t.label.as_deref() == Some(event))
        .filter(|t| from.is_none_or(|p| t.pre.iter().any(|a| a.place == p)))
        .map(|t| t.id.clone())
        .collect()
}

/// A rule as the constraints synthesis takes: an if–then rule on an event
/// (or on `event@place`) becomes one rule per transition labelled with it
/// (and taking from the place).
fn expand(net: &Net, rule: &str) -> Result<Vec<Constraint>, String> {
    let constraint = Constraint::parse(rule).map_err(|e| e.to_string())?;
    match &constraint {
        Constraint::IfThenNot { place, transition } if net.transition(transition).is_none() => {
            let ids = labelled(net, transition);
            if ids.is_empty() {
                return Err(format!("no transition or event is called '{transition}'"));
            }
            Ok(ids
                .into_iter()
                .map(|id| Constraint::IfThenNot {
                    place: place.clone(),
                    transition: id,
                })
                .collect())
        }
        _ => Ok(vec![constraint]),
    }
}

/// What synthesis added, by the rule it enforces; monitor places renamed
/// after the rule's number (`rule8`), which the net keeps when rules are
/// added or reordered elsewhere.
fn per_rule(
    net: &mut Net,
    design: &LabDesign,
    constraints: &[Vec<Constraint>],
    added: Vec<Added>,
) -> Vec<(Rule, Vec<Added>)> {
    let mut added = added.into_iter();
    design
        .controllers
        .iter()
        .zip(constraints)
        .enumerate()
        .map(|(n, (rule, expanded))| {
            let mine: Vec<Added> = added
                .by_ref()
                .take(expanded.len())
                .map(|a| match a {
                    Added::Monitor {
                        place,
                        initial,
                        enforced,
                    } => {
                        let id = format!("rule{}", n + 1);
                        if let Some(p) = net.place(&place) {
                            net.places[p.0].id = id.clone();
                        }
                        Added::Monitor {
                            place: id,
                            initial,
                            enforced,
                        }
                    }
                    other => other,
                })
                .collect();
            (rule.clone(), mine)
        })
        .collect()
}

/// For each rule, the shortest firing sequence of `net` that breaks it.
fn breaks(
    net: &Net,
    space: &StateSpace,
    design: &LabDesign,
    constraints: &[Vec<Constraint>],
) -> Vec<(Rule, Option<Interleaving>)> {
    design
        .controllers
        .iter()
        .zip(constraints)
        .map(|(rule, constraints)| (rule.clone(), broken(net, space, constraints)))
        .collect()
}

/// The shortest firing sequence that reaches a marking breaking one of
/// `constraints` (a linear one), or fires a forbidden transition in it.
fn broken(net: &Net, space: &StateSpace, constraints: &[Constraint]) -> Option<Interleaving> {
    let place = |id: &str| net.place(id);
    for s in 0..space.states() {
        let m = space.marking(s);
        for c in constraints {
            let last = match c {
                Constraint::Linear { terms, bound } => {
                    let value: i64 = terms
                        .iter()
                        .filter_map(|(p, k)| place(p).map(|p| k * i64::from(m.tokens(p))))
                        .sum();
                    if value <= *bound {
                        continue;
                    }
                    None
                }
                Constraint::IfThenNot {
                    place: p,
                    transition,
                } => {
                    let (Some(p), Some(t)) = (place(p), net.transition(transition)) else {
                        continue;
                    };
                    if m.tokens(p) == 0 || !net.is_enabled(&m, t) {
                        continue;
                    }
                    Some(t.0)
                }
            };
            let fired: Vec<usize> = firing_sequence(space, s).into_iter().chain(last).collect();
            return Some(events(net, &fired));
        }
    }
    None
}

/// The events of the transitions `fired` (a transition's label, or its id).
fn events(net: &Net, fired: &[usize]) -> Interleaving {
    let tr = |t: &usize| &net.transitions[*t];
    Interleaving {
        events: fired
            .iter()
            .map(|t| tr(t).label.clone().unwrap_or_else(|| tr(t).id.clone()))
            .collect(),
    }
}

/// Every event the design names is some chart's. The lab fires a
/// component's event when the component has done its part: a chart
/// waiting for one the run lacks would wait forever, and one the charts
/// lack would be refused at every run.
fn events_known(design: &LabDesign, lab: &str, composed: &Net) -> Result<(), DesignError> {
    if let Some(event) = design.uncontrollable.iter().find(|event| {
        labelled(composed, event).is_empty() && !NEVER_FORBIDDEN.contains(&event.as_str())
    }) {
        return Err(DesignError::UnknownEvent {
            lab: lab.to_owned(),
            event: event.clone(),
        });
    }
    let Some(declared) = &design.experiment else {
        return Ok(());
    };
    let experiment: &Experiment = &declared.experiment;
    for component in RunComponent::ALL {
        let Some(event) = component.event() else {
            continue;
        };
        let in_charts = !labelled(composed, event).is_empty();
        let in_run = experiment.run.has(component);
        if in_charts != in_run {
            let why = match in_run {
                true => format!("the component {component} fires '{event}', which no chart has"),
                false => format!(
                    "a chart waits for '{event}', which only the component {component} fires, and [run] has no {component}"
                ),
            };
            return Err(DesignError::Component {
                lab: lab.to_owned(),
                why,
            });
        }
    }
    Ok(())
}
