//! README's "Try it" and Petri blocks, run as written, one after another,
//! from a directory that is not the repository (so nothing may read a
//! file of the repository), failing on any command that exits non-zero or
//! says an error.
//!
//! What differs from a person at a terminal, and only that:
//! - commands that serve until stopped (`host`, `media`, `khepera-emu`) run in the
//!   background until the next one of their kind, or the end;
//! - the window has a display-free variant: `guest` gets `--headless`
//!   (an observer, also `--timeout 1`: nobody drives while it watches);
//! - servers listen on a port of their own choosing, used in place of README's
//!   in later commands, and the emulator's link is in scratch space,
//!   so the test runs beside anything already on 7400;
//! - benchmarks run on small inputs: what is checked is that they run.

use crate::common;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use common::{VlProcess, scratch, start_vl_in, stderr, stdout};

/// The shell commands of README's ```sh block under `heading`, with
/// continuation lines joined and comments dropped.
pub(crate) fn commands_under(readme: &str, heading: &str) -> Vec<String> {
    let section = readme
        .split("\n## ")
        .find(|s| s.starts_with(heading))
        .unwrap_or_else(|| panic!("README has no section {heading:?}"));
    let block = section
        .split("```sh\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .unwrap_or_else(|| panic!("{heading:?} has no sh block"));
    let mut commands = Vec::new();
    let mut current = String::new();
    for line in block.lines() {
        let line = strip_comment(line);
        match line.trim_end().strip_suffix('\\') {
            Some(part) => current.push_str(part),
            None => {
                current.push_str(line);
                if !current.trim().is_empty() {
                    commands.push(current.trim().to_owned());
                }
                current.clear();
            }
        }
    }
    commands
}

/// The line up to a `#` that starts a comment (outside quotes).
fn strip_comment(line: &str) -> &str {
    let mut quoted = false;
    for (i, c) in line.char_indices() {
        match c {
            '\'' => quoted = !quoted,
            '#' if !quoted && (i == 0 || line[..i].ends_with(' ')) => return &line[..i],
            _ => {}
        }
    }
    line
}

/// Splits a command into words as a POSIX shell does for these commands:
/// blanks separate, single quotes group.
fn words(command: &str) -> Vec<String> {
    let (mut out, mut word, mut quoted, mut any) = (Vec::new(), String::new(), false, false);
    for c in command.chars() {
        match c {
            '\'' => {
                quoted = !quoted;
                any = true;
            }
            c if c.is_whitespace() && !quoted => {
                if any {
                    out.push(std::mem::take(&mut word));
                    any = false;
                }
            }
            c => {
                word.push(c);
                any = true;
            }
        }
    }
    if any {
        out.push(word);
    }
    out
}

/// The arguments to `vl` in a README command.
pub(crate) fn vl_args(command: &str) -> Vec<String> {
    let w = words(command);
    if w.len() > 4 && w[..4] == ["cargo", "run", "--release", "--"] {
        w[4..].to_vec()
    } else if w.first().is_some_and(|c| c == "vl") {
        w[1..].to_vec()
    } else {
        panic!("README command does not run vl: {command}")
    }
}

/// What the test changes in a command, as the module says.
fn for_test(args: &mut Vec<String>, ports: &[(String, String)], link: &str) {
    let mut after_listen = false;
    for arg in args.iter_mut() {
        // A server's own address is README's, for the caller to replace.
        if !std::mem::replace(&mut after_listen, arg == "--listen") {
            for (from, to) in ports {
                *arg = arg.replace(from, to);
            }
        }
        *arg = arg.replace("/tmp/khepera", link);
    }
    let has = |a: &[String], flag: &str| a.iter().any(|x| x == flag);
    match args.first().map(String::as_str) {
        Some("guest") if !has(args, "--headless") => {
            args.push("--headless".into());
            if has(args, "--observer") {
                args.extend(["--timeout".into(), "1".into()]);
            }
        }
        Some("plan") if args.get(1).map(String::as_str) == Some("bench") => {
            args.extend(["--size", "200", "--runs", "2"].map(String::from));
        }
        Some("petri") if args.get(1).map(String::as_str) == Some("bench") => {
            args.extend(["--model", "SwimmingPool-PT-02"].map(String::from));
        }
        Some("media") if args.get(1).map(String::as_str) == Some("bench") => {
            args.extend(["--messages", "200", "--profiles", "lan"].map(String::from));
        }
        Some("host") if args.get(1).map(String::as_str) == Some("bench") => {
            args.extend(["--commands", "50"].map(String::from));
        }
        Some("host") if args.get(1).map(String::as_str) == Some("bench-watchers") => {
            args.extend(["--commands", "100", "--rounds", "1"].map(String::from));
        }
        // The whole matrix runs in tests/experiment_media.rs.
        Some("experiment") if args.get(1).map(String::as_str) == Some("report") => {
            args.extend(["--profiles", "lan", "--seeds", "2"].map(String::from));
        }
        // Every arena through the realistic camera: tests/camera_follow.rs.
        Some("experiment") if args.get(1).map(String::as_str) == Some("run") => {
            let arena = args.iter().position(|a| a == "--arena").map(|i| i + 1);
            if let Some(all) = arena.filter(|&i| args.get(i).is_some_and(|a| a == "all")) {
                args[all] = "open".into();
            }
        }
        _ => {}
    }
}

/// What a command said on stderr that is an error rather than progress.
fn complaint(said: &str) -> Option<&str> {
    said.lines().find(|l| {
        let lower = l.to_lowercase();
        lower.contains("error")
            || lower.contains("panicked")
            || l.starts_with("vl:")
            || l.contains("WARN")
    })
}

#[test]
fn every_command_in_readme_runs_as_written() {
    let readme = include_str!("../README.md");
    let dir = scratch("readme");
    // README's address of each server → where it really listens.
    let mut ports: Vec<(String, String)> = Vec::new();
    let link = dir.join("khepera");
    let link = link.to_str().unwrap();
    let mut servers: Vec<(String, VlProcess)> = Vec::new();
    let mut ran = 0;
    for heading in ["Try it", "Petri nets"] {
        for command in commands_under(readme, heading) {
            let (vl_part, piped_to) = match command.split_once(" | ") {
                Some((vl, rest)) => (vl.to_owned(), Some(rest.to_owned())),
                None => (command.clone(), None),
            };
            let mut args = vl_args(&vl_part);
            for_test(&mut args, &ports, link);
            let argv: Vec<&str> = args.iter().map(String::as_str).collect();
            println!("$ vl {}", argv.join(" "));
            let kind = argv[0];
            let serves = match kind {
                "khepera-emu" => true,
                "host" => !matches!(argv.get(1), Some(&"bench" | &"bench-watchers")),
                "media" => argv.get(1) != Some(&"bench"),
                _ => false,
            };
            if serves {
                // One of each kind at a time, as one person would run them.
                servers.retain(|(k, _)| k != kind);
                let prefix = match kind {
                    "host" => "vl host listening on ",
                    "media" => "vl media listening on ",
                    _ => "vl khepera-emu: ",
                };
                // Bound by the server itself: a port picked beforehand
                // could be taken by a parallel test in the meantime.
                let mut argv = argv.clone();
                let readme_addr = argv
                    .iter()
                    .position(|a| *a == "--listen")
                    .map(|i| std::mem::replace(&mut argv[i + 1], "127.0.0.1:0"));
                let (process, said) = start_vl_in(Some(&dir), &argv, prefix);
                println!("  {prefix}{said}");
                if let Some(readme_addr) = readme_addr {
                    let bound = said
                        .strip_prefix("ws://")
                        .and_then(|s| s.split_whitespace().next())
                        .unwrap_or_else(|| panic!("{kind} said no address: {said}"));
                    ports.retain(|(from, _)| from != readme_addr);
                    ports.push((readme_addr.to_owned(), bound.to_owned()));
                }
                servers.push((kind.to_owned(), process));
                ran += 1;
                continue;
            }
            let began = std::time::Instant::now();
            let out = common::vl_command()
                .args(&argv)
                .current_dir(&dir)
                .env_remove("DISPLAY")
                .env_remove("WAYLAND_DISPLAY")
                .output()
                .expect("vl runs");
            println!("  took {:.1} s", began.elapsed().as_secs_f64());
            assert!(
                out.status.success(),
                "`{command}` exited {:?}:\n{}",
                out.status,
                stderr(&out)
            );
            if let Some(line) = complaint(&stderr(&out)) {
                panic!("`{command}` said an error: {line}");
            }
            if let Some(pipe) = piped_to {
                check_pipe(&dir, &pipe, &stdout(&out));
            }
            ran += 1;
        }
    }
    assert!(ran >= 20, "only {ran} commands found in README");
}

/// `… | dot -Tsvg > file`: through Graphviz where it is installed, else
/// the output must at least be a DOT graph.
fn check_pipe(dir: &Path, pipe: &str, output: &str) {
    let w = words(pipe);
    assert_eq!(
        w.first().map(String::as_str),
        Some("dot"),
        "unexpected pipe: {pipe}"
    );
    let (args, target) = match w.iter().position(|x| x == ">") {
        Some(i) => (&w[1..i], w.get(i + 1)),
        None => (&w[1..], None),
    };
    let Ok(mut dot) = Command::new("dot")
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
    else {
        common::missing("Graphviz's dot", ".ci/run installs Debian's graphviz");
        assert!(output.starts_with("digraph"), "not DOT: {output}");
        return;
    };
    dot.stdin
        .take()
        .unwrap()
        .write_all(output.as_bytes())
        .unwrap();
    let out = dot.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "dot refused vl's output: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    if let Some(file) = target {
        std::fs::write(dir.join(file), &out.stdout).unwrap();
    }
    assert!(String::from_utf8_lossy(&out.stdout).contains("<svg"));
}

#[test]
fn the_splitter_reads_readme_as_a_shell_would() {
    assert_eq!(
        words("vl petri control lab.pnml --constraint 'a + b <= 1' -o x.pnml"),
        [
            "vl",
            "petri",
            "control",
            "lab.pnml",
            "--constraint",
            "a + b <= 1",
            "-o",
            "x.pnml"
        ]
    );
    assert_eq!(strip_comment("vl demo   # a comment"), "vl demo   ");
    assert_eq!(
        strip_comment("vl x --constraint 'a #b'"),
        "vl x --constraint 'a #b'"
    );
    let readme = "# vl\n## Try it\n\n```sh\nvl a \\\n    b  # c\nvl d\n```\n";
    assert_eq!(commands_under(readme, "Try it"), ["vl a     b", "vl d"]);
}
