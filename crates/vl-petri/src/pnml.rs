//! PNML (ISO/IEC 15909-2) place/transition nets in and out, so nets move to
//! and from TAPAAL, PIPE, GreatSPN, Tina and LoLA, and the Model Checking
//! Contest's models load as they are.
//!
//! Read: nested pages and reference nodes (multi-page nets), initial
//! markings and inscriptions as `<text>` (standard) or `<value>Default,N`
//! (PIPE), inhibitor arcs as `<type value="inhibitor"/>` (PIPE) or
//! `type="tapnInhibitor"` (TAPAAL), capacities as PIPE's `<capacity>`, and
//! transition labels in a `vl` tool-specific element. Written: one page,
//! the same conventions, so export → import is the identity.

use std::collections::HashMap;
use std::fmt::Write;

use roxmltree::{Document, Node};
use thiserror::Error;

use crate::lines::LineStarts;
use crate::net::{ArcKind, Net, NetError, TransitionId};

/// What is wrong with a PNML document, and where (line numbers are 1-based).
#[derive(Debug, Error, PartialEq, Eq)]
pub enum PnmlError {
    #[error("not well-formed XML: {0}")]
    Xml(String),
    #[error("no <net> element in the document")]
    NoNet,
    #[error("line {line}: <{element}> has no id attribute")]
    MissingId { element: String, line: u32 },
    #[error("line {line}: id '{id}' is used twice")]
    DuplicateId { id: String, line: u32 },
    #[error("line {line}: {what} '{value}' is not a whole number")]
    BadNumber {
        what: String,
        value: String,
        line: u32,
    },
    #[error("line {line}: {what} {value} is negative")]
    Negative { what: String, value: i64, line: u32 },
    #[error("line {line}: arc '{arc}' has weight 0")]
    ZeroWeight { arc: String, line: u32 },
    #[error("line {line}: arc '{arc}' refers to missing node '{node}'")]
    MissingNode {
        arc: String,
        node: String,
        line: u32,
    },
    #[error("line {line}: arc '{arc}' must join a place and a transition")]
    SameKind { arc: String, line: u32 },
    #[error("line {line}: inhibitor arc '{arc}' must run from a place to a transition")]
    InhibitorDirection { arc: String, line: u32 },
    #[error("line {line}: reference '{id}' points to missing node '{target}'")]
    DanglingReference {
        id: String,
        target: String,
        line: u32,
    },
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum NodeKind {
    Place,
    Transition,
}

/// A net read from `text`.
pub fn from_pnml(text: &str) -> Result<Net, PnmlError> {
    let doc = Document::parse(text).map_err(|e| PnmlError::Xml(e.to_string()))?;
    let net_node = doc
        .descendants()
        .find(|n| n.has_tag_name_local("net"))
        .ok_or(PnmlError::NoNet)?;
    let mut reader = Reader {
        lines: LineStarts::new(text),
        net: Net::new(net_node.attribute("id").unwrap_or("net")),
        kinds: HashMap::new(),
        alias: HashMap::new(),
    };
    // Nodes first, from every page; arcs once every node is known.
    let mut references: Vec<(String, String, u32)> = Vec::new();
    let mut arcs = Vec::new();
    for n in net_node.descendants().filter(Node::is_element) {
        let tag = n.tag_name().name();
        if !matches!(
            tag,
            "place" | "transition" | "referencePlace" | "referenceTransition" | "arc"
        ) {
            continue;
        }
        let id = n
            .attribute("id")
            .ok_or_else(|| PnmlError::MissingId {
                element: tag.to_owned(),
                line: reader.line(n),
            })?
            .to_owned();
        match tag {
            "place" => reader.place(n, id)?,
            "transition" => reader.transition(n, id)?,
            "referencePlace" | "referenceTransition" => {
                let target = n.attribute("ref").unwrap_or_default().to_owned();
                references.push((id, target, reader.line(n)));
            }
            _ => arcs.push(n),
        }
    }
    reader.references(&references)?;
    for a in arcs {
        reader.arc(a)?;
    }
    Ok(reader.net)
}

/// A net as it is read: its nodes' kinds by id, and what each reference
/// node stands for.
struct Reader {
    lines: LineStarts,
    net: Net,
    kinds: HashMap<String, NodeKind>,
    alias: HashMap<String, String>,
}

impl Reader {
    fn line(&self, n: Node) -> u32 {
        self.lines.of(n.range().start)
    }

    /// `id` is a new node of `kind`, or the net has it twice.
    fn new_node(&mut self, n: Node, id: &str, kind: NodeKind) -> Result<(), PnmlError> {
        if self.kinds.insert(id.to_owned(), kind).is_some() {
            return Err(self.duplicate(n, id));
        }
        Ok(())
    }

    fn duplicate(&self, n: Node, id: &str) -> PnmlError {
        PnmlError::DuplicateId {
            id: id.to_owned(),
            line: self.line(n),
        }
    }

    fn place(&mut self, n: Node, id: String) -> Result<(), PnmlError> {
        self.new_node(n, &id, NodeKind::Place)?;
        let p = self
            .net
            .add_place(&id, 0)
            .map_err(|_| self.duplicate(n, &id))?;
        let initial = match child(n, "initialMarking") {
            Some(m) => Some(number(m, "initial marking", self.line(m))?),
            None => None,
        };
        let capacity = match child(n, "capacity") {
            Some(c) => Some(number(c, "capacity", self.line(c))?),
            None => None,
        };
        let place = &mut self.net.places[p.0];
        place.name = name_of(n).unwrap_or_else(|| id.clone());
        if let Some(initial) = initial {
            place.initial = initial;
        }
        // PIPE writes 0 for "no capacity".
        if let Some(cap) = capacity {
            place.capacity = (cap > 0).then_some(cap);
        }
        Ok(())
    }

    fn transition(&mut self, n: Node, id: String) -> Result<(), PnmlError> {
        self.new_node(n, &id, NodeKind::Transition)?;
        let label = n
            .children()
            .filter(|c| c.has_tag_name_local("toolspecific") && c.attribute("tool") == Some("vl"))
            .find_map(|c| child(c, "label"))
            .and_then(|l| l.text())
            .map(str::trim);
        let t = self
            .net
            .add_transition(&id, label)
            .map_err(|_| self.duplicate(n, &id))?;
        self.net.transitions[t.0].name = name_of(n).unwrap_or(id);
        Ok(())
    }

    /// A reference node stands for the node it points to (possibly via
    /// other references); each must end at a node.
    fn references(&mut self, references: &[(String, String, u32)]) -> Result<(), PnmlError> {
        for (id, target, l) in references {
            if self.kinds.contains_key(id) || self.alias.contains_key(id) {
                return Err(PnmlError::DuplicateId {
                    id: id.clone(),
                    line: *l,
                });
            }
            self.alias.insert(id.clone(), target.clone());
        }
        for (id, target, l) in references {
            if self.resolve(id).is_none() {
                return Err(PnmlError::DanglingReference {
                    id: id.clone(),
                    target: target.clone(),
                    line: *l,
                });
            }
        }
        Ok(())
    }

    /// The node `id` names, through any references, and its kind.
    fn resolve(&self, id: &str) -> Option<(String, NodeKind)> {
        let mut current = id.to_owned();
        for _ in 0..=self.alias.len() {
            if let Some(kind) = self.kinds.get(&current) {
                return Some((current, *kind));
            }
            current = self.alias.get(&current)?.clone();
        }
        None
    }

    fn arc(&mut self, a: Node) -> Result<(), PnmlError> {
        let l = self.line(a);
        let id = a.attribute("id").unwrap_or_default().to_owned();
        let end = |attr: &str| {
            let node = a.attribute(attr).unwrap_or_default();
            self.resolve(node).ok_or_else(|| PnmlError::MissingNode {
                arc: id.clone(),
                node: node.to_owned(),
                line: l,
            })
        };
        let (source, source_kind) = end("source")?;
        let (target, target_kind) = end("target")?;
        let weight = match child(a, "inscription") {
            Some(w) => number(w, "arc weight", self.line(w))?,
            None => 1,
        };
        if weight == 0 {
            return Err(PnmlError::ZeroWeight { arc: id, line: l });
        }
        let inhibitor = a.attribute("type") == Some("tapnInhibitor")
            || child(a, "type").and_then(|t| t.attribute("value")) == Some("inhibitor");
        let (kind, place, transition) = match (source_kind, target_kind, inhibitor) {
            (NodeKind::Place, NodeKind::Transition, false) => (ArcKind::Input, source, target),
            (NodeKind::Place, NodeKind::Transition, true) => (ArcKind::Inhibitor, source, target),
            (NodeKind::Transition, NodeKind::Place, false) => (ArcKind::Output, target, source),
            (NodeKind::Transition, NodeKind::Place, true) => {
                return Err(PnmlError::InhibitorDirection { arc: id, line: l });
            }
            _ => return Err(PnmlError::SameKind { arc: id, line: l }),
        };
        let t: TransitionId = self
            .net
            .transition(&transition)
            .expect("resolved to a transition");
        self.net
            .add_arc(kind, &place, t, weight)
            .map_err(|e| match e {
                NetError::ZeroWeight { .. } => PnmlError::ZeroWeight {
                    arc: id.clone(),
                    line: l,
                },
                _ => PnmlError::MissingNode {
                    arc: id.clone(),
                    node: place.clone(),
                    line: l,
                },
            })?;
        Ok(())
    }
}

/// The first child element called `tag` (any namespace).
fn child<'a, 'i>(n: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name_local(tag))
}

/// The `<name><text>` of a node.
fn name_of(n: Node) -> Option<String> {
    child(n, "name")
        .and_then(|c| child(c, "text"))
        .and_then(|t| t.text())
        .map(|t| t.trim().to_owned())
}

/// A non-negative count in `<text>N</text>` or PIPE's `<value>Default,N</value>`.
fn number(n: Node, what: &str, line: u32) -> Result<u32, PnmlError> {
    let raw = child(n, "text")
        .or_else(|| child(n, "value"))
        .and_then(|t| t.text())
        .unwrap_or("")
        .trim();
    let digits = raw.rsplit(',').next().unwrap_or(raw).trim();
    let bad = || PnmlError::BadNumber {
        what: what.to_owned(),
        value: raw.to_owned(),
        line,
    };
    let value: i64 = digits.parse().map_err(|_| bad())?;
    if value < 0 {
        return Err(PnmlError::Negative {
            what: what.to_owned(),
            value,
            line,
        });
    }
    u32::try_from(value).map_err(|_| bad())
}

trait LocalName {
    fn has_tag_name_local(&self, name: &str) -> bool;
}

impl LocalName for Node<'_, '_> {
    fn has_tag_name_local(&self, name: &str) -> bool {
        self.is_element() && self.tag_name().name() == name
    }
}

/// The PNML text of `net`, on one page.
pub fn to_pnml(net: &Net) -> String {
    let mut out = String::new();
    let e = escape;
    out.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    out.push_str("<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n");
    let _ = writeln!(
        out,
        "  <net id=\"{}\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\">",
        e(&net.id)
    );
    out.push_str("    <page id=\"page0\">\n");
    for p in &net.places {
        let _ = write!(
            out,
            "      <place id=\"{}\"><name><text>{}</text></name>",
            e(&p.id),
            e(&p.name)
        );
        if p.initial > 0 {
            let _ = write!(
                out,
                "<initialMarking><text>{}</text></initialMarking>",
                p.initial
            );
        }
        if let Some(cap) = p.capacity {
            let _ = write!(out, "<capacity><value>{cap}</value></capacity>");
        }
        out.push_str("</place>\n");
    }
    for t in &net.transitions {
        let _ = write!(
            out,
            "      <transition id=\"{}\"><name><text>{}</text></name>",
            e(&t.id),
            e(&t.name)
        );
        if let Some(label) = &t.label {
            let _ = write!(
                out,
                "<toolspecific tool=\"vl\" version=\"1\"><label>{}</label></toolspecific>",
                e(label)
            );
        }
        out.push_str("</transition>\n");
    }
    let mut n = 0;
    for t in &net.transitions {
        for (kind, arc) in t.arcs() {
            let place = &net.places[arc.place.0].id;
            let (source, target) = match kind {
                ArcKind::Output => (&t.id, place),
                ArcKind::Input | ArcKind::Inhibitor => (place, &t.id),
            };
            let _ = write!(
                out,
                "      <arc id=\"arc{n}\" source=\"{}\" target=\"{}\"><inscription><text>{}</text></inscription>",
                e(source),
                e(target),
                arc.weight
            );
            if kind == ArcKind::Inhibitor {
                out.push_str("<type value=\"inhibitor\"/>");
            }
            out.push_str("</arc>\n");
            n += 1;
        }
    }
    out.push_str("    </page>\n  </net>\n</pnml>\n");
    out
}

fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_PAGES: &str = r#"<?xml version="1.0"?>
<pnml xmlns="http://www.pnml.org/version-2009/grammar/pnml">
 <net id="two" type="http://www.pnml.org/version-2009/grammar/ptnet">
  <page id="a">
   <place id="p"><name><text>ready</text></name><initialMarking><text>2</text></initialMarking></place>
   <transition id="t"/>
   <page id="inner">
     <referencePlace id="p_ref" ref="p"/>
     <place id="q"><initialMarking><value>Default,0</value></initialMarking></place>
     <arc id="a1" source="p_ref" target="t"><inscription><text>2</text></inscription></arc>
   </page>
  </page>
  <page id="b">
   <arc id="a2" source="t" target="q"/>
   <arc id="a3" source="q" target="t" type="tapnInhibitor"/>
  </page>
 </net>
</pnml>"#;

    #[test]
    fn reads_pages_references_and_inhibitors() {
        let net = from_pnml(TWO_PAGES).unwrap();
        assert_eq!(net.places.len(), 2);
        assert_eq!(net.places[0].name, "ready");
        assert_eq!(net.initial_marking().0, vec![2, 0]);
        let t = &net.transitions[0];
        assert_eq!((t.pre[0].place.0, t.pre[0].weight), (0, 2));
        assert_eq!((t.post[0].place.0, t.post[0].weight), (1, 1));
        assert_eq!(t.inhibit[0].place.0, 1);
        assert_eq!(from_pnml(&to_pnml(&net)).unwrap(), net);
    }

    #[test]
    fn errors_name_the_problem_and_line() {
        let truncated = &TWO_PAGES[..TWO_PAGES.len() / 2];
        assert!(matches!(from_pnml(truncated), Err(PnmlError::Xml(_))));
        let missing = TWO_PAGES.replace(r#"target="q"/>"#, r#"target="nowhere"/>"#);
        assert_eq!(
            from_pnml(&missing),
            Err(PnmlError::MissingNode {
                arc: "a2".into(),
                node: "nowhere".into(),
                line: 14
            })
        );
        let negative = TWO_PAGES.replace(
            "<text>2</text></inscription>",
            "<text>-2</text></inscription>",
        );
        let e = from_pnml(&negative).unwrap_err();
        assert!(e.to_string().contains("arc weight -2 is negative"), "{e}");
        let zero = TWO_PAGES.replace(
            "<text>2</text></inscription>",
            "<text>0</text></inscription>",
        );
        assert!(matches!(
            from_pnml(&zero),
            Err(PnmlError::ZeroWeight { .. })
        ));
        let dangling = TWO_PAGES.replace(r#"ref="p""#, r#"ref="ghost""#);
        assert!(matches!(
            from_pnml(&dangling),
            Err(PnmlError::DanglingReference { .. })
        ));
        assert_eq!(from_pnml("<pnml/>"), Err(PnmlError::NoNet));
    }
}
