//! What `vl lab nets` writes for a lab: its nets as PNML and DOT, and a
//! report that reads like the thesis's analysis of it.

use std::fmt::Write;
use std::path::Path;

use vl_petri::{Added, Analysis, net_to_dot, render_svg, to_pnml};

use super::pipeline::{Interleaving, Stuck};
use super::{DesignError, Designed};

impl Designed {
    /// Each file's name in the lab's folder and its contents.
    pub fn files(&self) -> Vec<(String, String)> {
        vec![
            ("uncontrolled.pnml".into(), to_pnml(&self.uncontrolled)),
            ("controlled.pnml".into(), to_pnml(&self.controlled)),
            ("uncontrolled.dot".into(), net_to_dot(&self.uncontrolled)),
            ("controlled.dot".into(), net_to_dot(&self.controlled)),
            ("report.md".into(), self.report()),
        ]
    }

    /// Writes the lab's files into `dir`, and SVG pictures of its nets
    /// when `pictures` (Graphviz's `dot`); the names written.
    pub fn write(&self, dir: &Path, pictures: bool) -> Result<Vec<String>, DesignError> {
        let failed = |path: &Path, why: String| DesignError::Write {
            path: path.display().to_string(),
            why,
        };
        std::fs::create_dir_all(dir).map_err(|e| failed(dir, e.to_string()))?;
        let mut written = Vec::new();
        for (name, text) in self.files() {
            let path = dir.join(&name);
            std::fs::write(&path, &text).map_err(|e| failed(&path, e.to_string()))?;
            if pictures && let Some(stem) = name.strip_suffix(".dot") {
                let svg = dir.join(format!("{stem}.svg"));
                render_svg(&path, &svg).map_err(|e| failed(&svg, e.to_string()))?;
                written.push(format!("{stem}.svg"));
            }
            written.push(name);
        }
        Ok(written)
    }

    /// Whether the controlled net has every property a lab needs, and no
    /// rule can be broken in it.
    pub fn sound(&self) -> bool {
        self.findings().is_empty()
    }

    /// What keeps the controlled net from being a lab's, each in words with
    /// the firing sequence that shows it: a dead end or no way back to the
    /// start (it is not reversible), an event that can never happen again,
    /// a chart in two states at once (not safe: only a chart several
    /// people share may hold more than one token), a rule still broken.
    pub fn findings(&self) -> Vec<String> {
        let a = &self.controlled_analysis;
        let mut found = Vec::new();
        let shown = |i: &Interleaving| match i.events.is_empty() {
            true => "at the start".to_owned(),
            false => format!("after {}", i.events.join(" → ")),
        };
        match &self.stuck {
            Some(Stuck {
                after,
                dead_end: true,
            }) => found.push(format!("a dead end: {}, nothing can happen", shown(after))),
            Some(Stuck { after, .. }) => found.push(format!(
                "no way back: {}, the session can never return to where it started",
                shown(after)
            )),
            None if !a.live => {
                found.push("an event can never happen again once the session has begun".to_owned())
            }
            None => {}
        }
        if !a.bounded {
            found.push("a place can hold ever more tokens".to_owned());
        } else if !a.safe && self.design.people.is_empty() {
            found.push(format!(
                "a chart can be in {} states at once",
                a.max_tokens_in_place
            ));
        }
        for (rule, broken) in &self.still_bad {
            if let Some(broken) = broken {
                found.push(format!(
                    "the rule '{}' ({}) is still broken {}",
                    rule.rule,
                    rule.why,
                    shown(broken)
                ));
            }
        }
        found
    }

    fn report(&self) -> String {
        let d = &self.design;
        let mut out = String::new();
        let _ = writeln!(out, "# {}: the lab's nets\n", d.title);
        let _ = writeln!(
            out,
            "Written by `vl lab nets` from `{source}` (its charts, beside it or shared, and \
             its design); do not edit: change a chart and run it again. The Host runs the \
             controlled net, `controlled.pnml`.\n",
            source = d.source
        );
        out.push_str("## The charts, each on its own\n\n");
        out.push_str(&table_head("chart"));
        for ((name, _), (_, analysis)) in d.charts.iter().zip(&self.charts) {
            out.push_str(&table_row(&format!("`{name}`"), analysis));
        }
        let u = &self.uncontrolled_analysis;
        let _ = writeln!(
            out,
            "\n## The composition, without controllers\n\n\
             The charts composed by their shared events (synchronous transition \
             composition): {} places, {} transitions ({} combinations of shared \
             events that can never fire left out), {} reachable markings.\n",
            u.places, u.transitions, self.never_fire, u.states
        );
        out.push_str(&table_head("net"));
        out.push_str(&table_row("uncontrolled", u));
        out.push_str("\n## What goes wrong without the controllers\n\n");
        out.push_str(
            "For each rule the lab needs, the shortest firing sequence of the uncontrolled \
             net that breaks it:\n\n",
        );
        for (rule, bad) in &self.bad {
            let _ = writeln!(
                out,
                "- {} (`{}`): {}",
                rule.why,
                rule.rule,
                sequence(bad.as_ref())
            );
        }
        out.push_str("\n## The controllers\n\n");
        for (rule, added) in &self.added {
            let _ = writeln!(out, "- {}: {}", rule.why, self.controllers(added));
        }
        let c = &self.controlled_analysis;
        let _ = writeln!(
            out,
            "\n## The controlled net\n\n\
             The composition with its controllers; {} transitions the controllers \
             disable for good left out, then parallel places fused: {} places, {} \
             transitions, {} reachable markings.\n",
            self.disabled, c.places, c.transitions, c.states
        );
        out.push_str(&table_head("net"));
        out.push_str(&table_row("controlled", c));
        out.push_str("\nEach rule, in the controlled net:\n\n");
        for (rule, bad) in &self.still_bad {
            let _ = writeln!(
                out,
                "- {}: {}",
                rule.why,
                match bad {
                    None => "cannot be broken".to_owned(),
                    Some(_) => format!("**still broken**: {}", sequence(bad.as_ref())),
                }
            );
        }
        let _ = writeln!(
            out,
            "\n{}\n\n![the uncontrolled net](uncontrolled.svg)\n\n![the controlled net](controlled.svg)",
            match (self.sound(), self.design.people.is_empty()) {
                (true, true) => "**The controlled net is bounded, safe, live, reversible and \
                 deadlock-free, and no rule can be broken in it.**"
                    .to_owned(),
                (true, false) => format!(
                    "**The controlled net is bounded, live, reversible and deadlock-free, and no \
                     rule can be broken in it.** It is not safe: {}'s places hold a token per \
                     person.",
                    self.people()
                ),
                (false, _) => "**The controlled net is NOT sound: see above.**".to_owned(),
            }
        );
        out
    }
}

impl Designed {
    /// The charts that are several people's, as `access (3 people)`.
    fn people(&self) -> String {
        let d = &self.design;
        d.people
            .iter()
            .map(|(chart, n)| format!("`{chart}` ({n} people)"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// What synthesis added for one rule, in words.
    fn controllers(&self, added: &[Added]) -> String {
        let mut parts: Vec<String> = Vec::new();
        let mut arcs: Vec<(&str, &str, usize)> = Vec::new();
        for a in added {
            match a {
                Added::Monitor {
                    place,
                    initial,
                    enforced,
                } => parts.push(format!(
                    "monitor place `{place}` ({initial} token{}) keeping `{enforced}`",
                    if *initial == 1 { "" } else { "s" }
                )),
                Added::Inhibitor { place, transition } => {
                    let event = self
                        .uncontrolled
                        .transition(transition)
                        .and_then(|t| self.uncontrolled.transitions[t.0].label.as_deref())
                        .unwrap_or(transition);
                    match arcs.iter_mut().find(|(p, e, _)| p == place && *e == event) {
                        Some(arc) => arc.2 += 1,
                        None => arcs.push((place, event, 1)),
                    }
                }
            }
        }
        for (place, event, n) in arcs {
            parts.push(format!(
                "inhibitor arc{} from `{place}` to the {n} `{event}` transition{}",
                if n == 1 { "" } else { "s" },
                if n == 1 { "" } else { "s" }
            ));
        }
        parts.join("; ")
    }
}

fn sequence(bad: Option<&Interleaving>) -> String {
    match bad {
        None => "cannot happen".to_owned(),
        Some(i) if i.events.is_empty() => "the initial marking".to_owned(),
        Some(i) => i
            .events
            .iter()
            .map(|e| format!("`{e}`"))
            .collect::<Vec<_>>()
            .join(" → "),
    }
}

fn yes(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

fn table_head(first: &str) -> String {
    format!(
        "| {first} | places | transitions | markings | bounded | safe | live | reversible | deadlock-free |\n\
         |---|---|---|---|---|---|---|---|---|\n"
    )
}

fn table_row(name: &str, a: &Analysis) -> String {
    format!(
        "| {name} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
        a.places,
        a.transitions,
        a.states,
        yes(a.bounded),
        yes(a.safe),
        yes(a.live),
        yes(a.reversible),
        yes(!a.deadlock)
    )
}
