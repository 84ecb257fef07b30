//! The code's shape, checked from its files and manifests: dependencies
//! that point one way (command lines only in the binary, a Guest that does
//! not link the Host, the crate graph ARCHITECTURE.md draws), nothing under
//! `src/` that embeds documentation or test fixtures, no source file over
//! 700 lines, no files that import each other around a circle of any
//! length, no type name shown beyond its file in two crates, no public
//! function that says what went wrong as a bare `String`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// The most lines a source file outside `tests/` may have.
const MOST_LINES: usize = 700;

/// Every `.rs` file under `dir`.
pub(crate) fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}

/// The source roots: the binary's and each crate's.
pub(crate) fn roots() -> Vec<PathBuf> {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut roots = vec![top.join("src")];
    for entry in std::fs::read_dir(top.join("crates")).unwrap().flatten() {
        roots.push(entry.path().join("src"));
    }
    roots.sort();
    roots
}

/// The text of a file without its `#[cfg(test)] mod tests` and comments.
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => &text,
    };
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// `cargo` with `args`, in the workspace, offline: its output.
fn cargo(args: &[&str]) -> Vec<u8> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(args)
        .arg("--offline")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// Each workspace package's name and its normal (not dev or build)
/// dependencies' names, from the manifests.
fn workspace_dependencies() -> BTreeMap<String, BTreeSet<String>> {
    let metadata: Value =
        serde_json::from_slice(&cargo(&["metadata", "--format-version", "1", "--no-deps"]))
            .unwrap();
    metadata["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|d| d["kind"].is_null())
                .map(|d| d["name"].as_str().unwrap().to_owned())
                .collect();
            (p["name"].as_str().unwrap().to_owned(), deps)
        })
        .collect()
}

/// Every package `package` links on this machine, by name: its
/// dependencies, theirs, and so on.
fn linked_by(package: &str) -> BTreeSet<String> {
    let tree = cargo(&["tree", "-p", package, "-e", "normal", "--prefix", "none"]);
    String::from_utf8(tree)
        .unwrap()
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_owned)
        .collect()
}

#[test]
fn only_the_binary_parses_command_lines() {
    let with_clap: Vec<String> = workspace_dependencies()
        .into_iter()
        .filter(|(name, deps)| name != "vl" && deps.contains("clap"))
        .map(|(name, _)| name)
        .collect();
    assert!(
        with_clap.is_empty(),
        "libraries that depend on clap: {with_clap:?}: a library takes typed options; \
         its flags belong in src/"
    );
}

#[test]
fn the_guest_links_no_server() {
    let linked = linked_by("vl-guest");
    for server in [
        "vl-host",
        "vl-sim",
        "vl-campaign",
        "axum",
        "argon2",
        "serialport",
    ] {
        assert!(
            !linked.contains(server),
            "the desktop Guest links {server}: what it shares with the Host belongs in \
             vl-core or vl-record"
        );
    }
    // The check sees what it looks for.
    assert!(linked.contains("vl-core") && linked.contains("tokio"));
    assert!(linked_by("vl-host").contains("axum"));
}

#[test]
fn the_lab_core_links_no_integration_and_measuring_no_window() {
    let host = linked_by("vl-host");
    for integration in [
        "vl-foxglove",
        "vl-cells",
        "vl-ros2",
        "vl-lti",
        "zenoh",
        "zenoh-ext",
        "jsonwebtoken",
        "rsa",
        "reqwest",
    ] {
        assert!(
            !host.contains(integration),
            "vl-host links {integration}: an integration plugs into the lab (an \
             Extension, a RobotPlug) from its own crate"
        );
    }
    let campaign = linked_by("vl-campaign");
    for window in ["eframe", "egui", "wgpu", "winit"] {
        assert!(
            !campaign.contains(window),
            "vl-campaign links {window}: measuring needs the client, not the window"
        );
    }
    // The checks see what they look for.
    assert!(linked_by("vl-cells").contains("zenoh") && host.contains("axum"));
    assert!(linked_by("vl-guest").contains("egui") && campaign.contains("vl-client"));
}

#[test]
fn architecture_draws_the_crate_graph_cargo_resolves() {
    let drawn: BTreeSet<(String, String)> =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("ARCHITECTURE.md"))
            .unwrap()
            .lines()
            .filter_map(|l| l.trim().split_once(" --> "))
            .map(|(a, b)| (a.to_owned(), b.to_owned()))
            .collect();
    let dependencies = workspace_dependencies();
    let ours: BTreeSet<&String> = dependencies.keys().collect();
    let resolved: BTreeSet<(String, String)> = dependencies
        .iter()
        .flat_map(|(name, deps)| {
            deps.iter()
                .filter(|d| ours.contains(d))
                .map(move |d| (name.clone(), d.clone()))
        })
        .collect();
    assert_eq!(
        drawn, resolved,
        "ARCHITECTURE.md's graph differs from the manifests"
    );
}

#[test]
fn no_source_embeds_documentation_or_test_fixtures() {
    let mut found = Vec::new();
    for root in roots() {
        for file in sources(&root) {
            let text = std::fs::read_to_string(&file).unwrap();
            for (at, _) in text
                .match_indices("include_str!(")
                .chain(text.match_indices("include_bytes!("))
            {
                let call = &text[at..text[at..].find(')').map_or(text.len(), |e| at + e)];
                if call.contains("docs/") || call.contains("tests/") {
                    found.push(format!("{}: {call})", file.display()));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "documentation or test files built in: {found:#?}"
    );
}

#[test]
fn no_source_file_is_over_700_lines() {
    let long: Vec<String> = roots()
        .iter()
        .flat_map(|r| sources(r))
        .filter(|p| !p.ends_with("tests.rs"))
        .filter_map(|p| {
            let n = std::fs::read_to_string(&p).unwrap().lines().count();
            (n > MOST_LINES).then(|| format!("{} ({n})", p.display()))
        })
        .collect();
    assert!(long.is_empty(), "over {MOST_LINES} lines: {long:?}");
}

/// A module's path within its crate, from its file.
fn module_of(root: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(root).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The paths `text` names through `crate::`, `super::` and `self::`, as
/// paths from the crate's root, for a file whose module is `module`.
fn named_paths(text: &str, module: &[String]) -> Vec<Vec<String>> {
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    let mut paths = Vec::new();
    for (head, base) in [
        ("crate::", Vec::new()),
        ("super::", module[..module.len().saturating_sub(1)].to_vec()),
        ("self::", module.to_vec()),
    ] {
        for (at, _) in text.match_indices(head) {
            if text[..at].chars().next_back().is_some_and(ident) {
                continue;
            }
            let mut path = base.clone();
            let mut rest = &text[at + head.len()..];
            loop {
                let name: String = rest.chars().take_while(|&c| ident(c)).collect();
                if name.is_empty() {
                    break;
                }
                path.push(name.clone());
                rest = &rest[name.len()..];
                match rest.strip_prefix("::") {
                    Some(r) => rest = r,
                    None => break,
                }
            }
            // A group `{a, b::c}` names each of its items.
            if let Some(group) = rest.strip_prefix('{') {
                let group = &group[..group.find('}').unwrap_or(group.len())];
                for item in group.split(',') {
                    let mut item_path = path.clone();
                    item_path.extend(
                        item.trim()
                            .split("::")
                            .map(|s| s.split(" as ").next().unwrap().trim().to_owned())
                            .filter(|s| !s.is_empty() && s != "self"),
                    );
                    paths.push(item_path);
                }
            }
            paths.push(path);
        }
    }
    paths
}

/// The circles in a graph of files: each strongly connected set of more
/// than one file (Tarjan's algorithm), whatever the circle's length.
fn circles(edges: &BTreeSet<(PathBuf, PathBuf)>) -> Vec<Vec<PathBuf>> {
    struct Walk<'a> {
        next: BTreeMap<&'a PathBuf, Vec<&'a PathBuf>>,
        index: BTreeMap<&'a PathBuf, usize>,
        low: BTreeMap<&'a PathBuf, usize>,
        stack: Vec<&'a PathBuf>,
        circles: Vec<Vec<PathBuf>>,
    }
    impl<'a> Walk<'a> {
        fn visit(&mut self, file: &'a PathBuf) {
            let i = self.index.len();
            self.index.insert(file, i);
            self.low.insert(file, i);
            self.stack.push(file);
            for to in self.next.get(file).cloned().unwrap_or_default() {
                if !self.index.contains_key(to) {
                    self.visit(to);
                    let low = self.low[file].min(self.low[to]);
                    self.low.insert(file, low);
                } else if self.stack.contains(&to) {
                    let low = self.low[file].min(self.index[to]);
                    self.low.insert(file, low);
                }
            }
            if self.low[file] == self.index[file] {
                let at = self.stack.iter().rposition(|f| *f == file).unwrap();
                let set: Vec<PathBuf> = self.stack.drain(at..).cloned().collect();
                if set.len() > 1 {
                    self.circles.push(set);
                }
            }
        }
    }
    let mut walk = Walk {
        next: BTreeMap::new(),
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        circles: Vec::new(),
    };
    for (a, b) in edges {
        walk.next.entry(a).or_default().push(b);
    }
    let files: Vec<&PathBuf> = walk.next.keys().copied().collect();
    for file in files {
        if !walk.index.contains_key(file) {
            walk.visit(file);
        }
    }
    walk.circles
}

/// Which file imports which, within each crate (and the binary), by the
/// paths each names through `crate::`, `super::` and `self::`.
fn imports() -> BTreeSet<(PathBuf, PathBuf)> {
    let mut edges = BTreeSet::new();
    for root in roots() {
        let files: BTreeMap<Vec<String>, PathBuf> = sources(&root)
            .into_iter()
            .map(|f| (module_of(&root, &f), f))
            .collect();
        let file_of = |path: &[String]| {
            (0..=path.len())
                .rev()
                .find_map(|n| files.get(&path[..n]).cloned())
        };
        for (module, file) in &files {
            for path in named_paths(&code(file), module) {
                if let Some(target) = file_of(&path)
                    && &target != file
                {
                    edges.insert((file.clone(), target));
                }
            }
        }
    }
    edges
}

#[test]
fn no_files_import_each_other_in_a_circle() {
    let found: Vec<String> = circles(&imports())
        .iter()
        .map(|set| {
            set.iter()
                .map(|f| f.display().to_string())
                .collect::<Vec<_>>()
                .join(" → ")
        })
        .collect();
    assert!(
        found.is_empty(),
        "files that import each other, around a circle: {found:#?}"
    );
}

/// Files whose types mirror an outside schema field by field and keep its
/// names (ROS 2's `.msg` files, Foxglove's schemas): a `Pose` there is the
/// schema's, whichever crate speaks it.
const SCHEMA_MIRRORS: [&str; 2] = [
    "crates/vl-ros2/src/messages.rs",
    "crates/vl-record/src/foxglove/messages.rs",
];

/// The types each crate shows beyond their file (`pub`, `pub(crate)`,
/// `pub(super)`), by name: which crates define each name.
fn shown_types() -> BTreeMap<String, BTreeSet<String>> {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut names: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for root in roots() {
        let krate = root
            .parent()
            .unwrap()
            .strip_prefix(top)
            .unwrap()
            .display()
            .to_string();
        for file in sources(&root) {
            let relative = file.strip_prefix(top).unwrap();
            if SCHEMA_MIRRORS.iter().any(|m| relative == Path::new(m)) {
                continue;
            }
            for line in code(&file).lines() {
                let Some(rest) = line.strip_prefix("pub") else {
                    continue;
                };
                let rest = match rest.strip_prefix('(') {
                    Some(r) => r.split_once(')').map_or("", |(_, r)| r),
                    None => rest,
                };
                let mut words = rest.split_whitespace();
                if let (Some("struct" | "enum" | "trait" | "type"), Some(name)) =
                    (words.next(), words.next())
                {
                    let name: String = name
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    names.entry(name).or_default().insert(krate.clone());
                }
            }
        }
    }
    names
}

#[test]
fn no_type_name_means_two_things() {
    let twice: Vec<String> = shown_types()
        .into_iter()
        .filter(|(_, crates)| crates.len() > 1)
        .map(|(name, crates)| format!("{name} in {crates:?}"))
        .collect();
    assert!(
        twice.is_empty(),
        "type names defined in two crates (name one of them for what it is): {twice:#?}"
    );
    // The check sees what it looks for.
    let shown = shown_types();
    assert!(shown["Arena"].contains("crates/vl-core"));
    assert!(shown["GuestApp"].contains("crates/vl-guest"));
}

#[test]
fn no_public_function_returns_a_string_as_its_error() {
    let mut found = Vec::new();
    let crates = roots()
        .into_iter()
        .filter(|r| r.components().any(|c| c.as_os_str() == "crates"));
    for root in crates {
        for file in sources(&root) {
            let text = code(&file);
            for (at, _) in text
                .match_indices("pub fn ")
                .chain(text.match_indices("pub async fn "))
            {
                let signature = &text[at..text[at..].find('{').map_or(text.len(), |e| at + e)];
                let returns = signature.rsplit("->").next().unwrap_or("");
                if signature.contains("->")
                    && returns.contains("Result<")
                    && returns.replace(' ', "").contains(",String>")
                {
                    found.push(format!(
                        "{}: {}",
                        file.display(),
                        signature.lines().next().unwrap()
                    ));
                }
            }
        }
    }
    assert!(found.is_empty(), "{found:#?}");
}

#[test]
fn the_checks_see_what_they_look_for() {
    // A mutual import and its paths, as the checker reads them.
    let module = vec!["server".to_owned(), "hub".to_owned()];
    let paths = named_paths("use super::connection::{error, Ticket};", &module);
    assert!(paths.contains(&vec!["server".into(), "connection".into(), "error".into()]));
    let paths = named_paths("use crate::lab::{Lab, map_field};", &module);
    assert!(paths.contains(&vec!["lab".into(), "map_field".into()]));
    assert!(named_paths("my_crate::x", &module).is_empty());
    // A circle of three is found, and a chain is not a circle.
    let edge = |a: &str, b: &str| (PathBuf::from(a), PathBuf::from(b));
    let mut edges = BTreeSet::from([
        edge("a", "b"),
        edge("b", "c"),
        edge("c", "a"),
        edge("c", "d"),
    ]);
    assert_eq!(circles(&edges).len(), 1);
    assert_eq!(circles(&edges)[0].len(), 3);
    edges.remove(&edge("c", "a"));
    assert!(circles(&edges).is_empty());
}
