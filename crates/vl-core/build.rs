//! Builds the shipped designs into vl: every experiment folder under
//! `assets/experiments/` (a folder with an `experiment.toml`), and the
//! shared charts and access design under `nets/`. A folder added there is
//! shipped by the next build, with no Rust naming it.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn main() {
    let here = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let experiments = here.join("../../assets/experiments");
    let nets = here.join("nets");
    let mut table = String::from("&[\n");
    // The shared ones first, then each experiment in its folder's order.
    for shared in ["common", "access"] {
        add_folder(&mut table, &nets.join(shared), shared);
    }
    for folder in folders(&experiments) {
        if folder.join("experiment.toml").is_file() {
            let name = folder
                .file_name()
                .and_then(|n| n.to_str())
                .expect("a folder's name");
            add_folder(&mut table, &folder, name);
        }
    }
    table.push(']');
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets it")).join("shipped.rs");
    std::fs::write(out, table).expect("OUT_DIR is writable");
    println!("cargo:rerun-if-changed={}", experiments.display());
    println!("cargo:rerun-if-changed={}", nets.join("common").display());
    println!("cargo:rerun-if-changed={}", nets.join("access").display());
}

/// The folders in `dir`, by name.
fn folders(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| entries.filter_map(|e| Some(e.ok()?.path())).collect())
        .unwrap_or_default();
    found.retain(|p| p.is_dir());
    found.sort();
    found
}

/// A table row per design file (`.toml`, `.scxml`) of `folder`, as
/// `name/file`; cargo builds again when one changes.
fn add_folder(table: &mut String, folder: &Path, name: &str) {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)
        .map(|entries| entries.filter_map(|e| Some(e.ok()?.path())).collect())
        .unwrap_or_default();
    files.retain(|p| {
        matches!(
            p.extension().and_then(|e| e.to_str()),
            Some("toml" | "scxml")
        )
    });
    // The design file first: `vl lab new` copies the charts after it.
    files.sort_by_key(|p| {
        (
            p.extension().and_then(|e| e.to_str()) != Some("toml"),
            p.clone(),
        )
    });
    for file in files {
        let file_name = file
            .file_name()
            .and_then(|n| n.to_str())
            .expect("a file's name");
        let path = file.canonicalize().expect("a listed file exists");
        let _ = writeln!(
            table,
            "    ({:?}, include_str!({:?})),",
            format!("{name}/{file_name}"),
            path
        );
        println!("cargo:rerun-if-changed={}", path.display());
    }
    println!("cargo:rerun-if-changed={}", folder.display());
}
