//! Docs that cannot drift: every file or folder ARCHITECTURE.md, README.md
//! and the crates' own docs name in backquotes exists, every module they
//! name as `vl-crate::module` is there, and every figure they quote from a
//! constant, written `256 (`MAX_CONNECTIONS`)`, is that constant's value.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::structure::{roots, sources};

/// Zenoh's link schemes, which look like folders in backquotes.
const SCHEMES: [&str; 4] = ["quic/", "tls/", "tcp/", "udp/"];

fn top() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The crates' folders, `crates/NAME`.
fn crates() -> Vec<PathBuf> {
    let mut crates: Vec<PathBuf> = std::fs::read_dir(top().join("crates"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    crates.sort();
    crates
}

/// The docs checked, with their text: the two at the top, the protocol,
/// and each crate's and the binary's own.
fn docs() -> Vec<(PathBuf, String)> {
    let mut docs = vec![
        top().join("ARCHITECTURE.md"),
        top().join("README.md"),
        top().join("docs/protocol.md"),
        top().join("src/main.rs"),
    ];
    docs.extend(crates().iter().map(|c| c.join("src/lib.rs")));
    docs.into_iter()
        .map(|d| {
            let text = std::fs::read_to_string(&d).unwrap();
            (d, text)
        })
        .collect()
}

/// What `text` holds in backquotes.
fn quoted(text: &str) -> Vec<&str> {
    text.split('`').skip(1).step_by(2).collect()
}

/// Whether `token` reads as a path of the repository: a file with an
/// extension we keep, or a folder (ending in `/`).
fn is_path(token: &str) -> bool {
    let plain = token
        .chars()
        .all(|c| c.is_alphanumeric() || "_-./".contains(c));
    let kept = [".rs", ".md", ".toml", ".py", ".sh", ".json", ".msg", "/"];
    plain
        && token.contains('/')
        && !token.starts_with('/')
        && kept.iter().any(|e| token.ends_with(e))
        && !SCHEMES.contains(&token)
}

/// Where a path in a doc may be written from: the top, `crates/`,
/// `tests/`, a crate, or a crate's sources.
fn bases() -> Vec<PathBuf> {
    let mut bases = vec![top().to_owned(), top().join("crates"), top().join("tests")];
    for krate in crates() {
        bases.push(krate.join("src"));
        bases.push(krate);
    }
    bases
}

/// The paths the docs name that are nowhere.
fn missing_paths(docs: &[(PathBuf, String)]) -> Vec<String> {
    let bases = bases();
    let mut missing = Vec::new();
    for (doc, text) in docs {
        for token in quoted(text).into_iter().filter(|t| is_path(t)) {
            if !bases.iter().any(|b| b.join(token).exists()) {
                missing.push(format!("{}: `{token}`", doc.display()));
            }
        }
    }
    missing
}

/// Whether `krate`'s sources have a module or an item called `name`.
fn has_module_or_item(krate: &Path, name: &str) -> bool {
    let src = krate.join("src");
    if src.join(format!("{name}.rs")).exists() || src.join(name).is_dir() {
        return true;
    }
    sources(&src).iter().any(|f| {
        let text = std::fs::read_to_string(f).unwrap();
        [
            "fn ", "mod ", "const ", "static ", "struct ", "enum ", "trait ",
        ]
        .iter()
        .any(|kind| {
            text.match_indices(&format!("{kind}{name}")).any(|(at, m)| {
                !text[at + m.len()..].starts_with(|c: char| c.is_alphanumeric() || c == '_')
            })
        })
    })
}

/// The `vl-crate::module` names the docs give that are not there.
fn missing_modules(docs: &[(PathBuf, String)]) -> Vec<String> {
    let mut missing = Vec::new();
    for (doc, text) in docs {
        for token in quoted(text) {
            let Some((krate, rest)) = token.split_once("::") else {
                continue;
            };
            let krate = krate.replace('_', "-");
            if !krate.starts_with("vl-") {
                continue;
            }
            let first: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let folder = top().join("crates").join(&krate);
            if !folder.is_dir() || !has_module_or_item(&folder, &first) {
                missing.push(format!("{}: `{token}`", doc.display()));
            }
        }
    }
    missing
}

/// Every `const NAME: T = VALUE;` in the workspace's sources, by name.
fn constants() -> BTreeMap<String, Vec<String>> {
    let mut constants: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for file in roots().iter().flat_map(|root| sources(root)) {
        let text = std::fs::read_to_string(&file).unwrap();
        for (at, _) in text.match_indices("const ") {
            let rest = &text[at + "const ".len()..];
            let Some((name, rest)) = rest.split_once(':') else {
                continue;
            };
            let Some(value) = rest
                .split_once('=')
                .and_then(|(_, v)| v.split_once(';'))
                .map(|(v, _)| v.trim().replace('_', ""))
            else {
                continue;
            };
            constants
                .entry(name.trim().to_owned())
                .or_default()
                .push(value);
        }
    }
    constants
}

/// The figures quoted as `N (`NAME`)` that differ from the constant (or
/// whose constant is gone).
fn wrong_figures(docs: &[(PathBuf, String)]) -> Vec<String> {
    let constants = constants();
    let mut wrong = Vec::new();
    for (doc, text) in docs {
        for (at, _) in text.match_indices(" (`") {
            let name: String = text[at + 3..]
                .chars()
                .take_while(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            if name.len() < 2 || !text[at + 3 + name.len()..].starts_with("`)") {
                continue;
            }
            // The figure may end the line before, in a doc comment.
            let before = text[..at].trim_end();
            let before = before.strip_suffix("//!").unwrap_or(before).trim_end();
            let figure: String = before
                .chars()
                .rev()
                .take_while(|c| c.is_ascii_digit() || *c == ',')
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .filter(|c| *c != ',')
                .collect();
            // A name after a word (`id (`ROS_DOMAIN_ID`)`) quotes no figure.
            if figure.is_empty() {
                continue;
            }
            let found = constants.get(&name);
            if found.is_none_or(|values| !values.contains(&figure)) {
                wrong.push(format!(
                    "{}: {figure} (`{name}`), the code says {found:?}",
                    doc.display()
                ));
            }
        }
    }
    wrong
}

#[test]
fn the_docs_name_only_paths_that_exist() {
    let docs = docs();
    let missing = missing_paths(&docs);
    assert!(missing.is_empty(), "named, but not there: {missing:#?}");
    // The check sees what it looks for.
    let made_up = [(
        PathBuf::from("x"),
        "`crates/vl-core/src/nowhere.rs`".to_owned(),
    )];
    assert_eq!(missing_paths(&made_up).len(), 1);
    assert!(is_path("crates/vl-host/src/lab/") && !is_path("quic/") && !is_path("a.b"));
}

#[test]
fn the_docs_name_only_modules_that_exist() {
    let docs = docs();
    let missing = missing_modules(&docs);
    assert!(missing.is_empty(), "named, but not there: {missing:#?}");
    let made_up = [(
        PathBuf::from("x"),
        "`vl-core::flag_file`, `vl-core::arena`".to_owned(),
    )];
    assert_eq!(missing_modules(&made_up).len(), 1);
}

#[test]
fn the_figures_docs_quote_from_constants_are_theirs() {
    let docs = docs();
    let wrong = wrong_figures(&docs);
    assert!(wrong.is_empty(), "{wrong:#?}");
    let quoted = docs
        .iter()
        .map(|(_, t)| t.matches(" (`MAX_").count())
        .sum::<usize>();
    assert!(quoted >= 3, "the admission's figures are quoted as checked");
    let made_up = [(
        PathBuf::from("x"),
        "at most 32 (`MAX_UNWELCOMED`)".to_owned(),
    )];
    assert_eq!(wrong_figures(&made_up).len(), 1);
}
