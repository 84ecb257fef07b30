//! A subcommand's flags kept in a TOML file (`vl host --config lab.toml`):
//! each key is a flag's long name, each value its value — so the file and
//! the command line are one set of options, with one home for each
//! option's meaning, default and check (the command's clap definition).
//! The file's flags go in first; flags given on the command line come
//! after them and win. Paths are read from the file's folder.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use clap::ValueHint;
use thiserror::Error;

/// The flag that names a flag file.
const FLAG: &str = "--config";

/// A flag file that cannot be used, and why.
#[derive(Debug, Error, PartialEq, Eq)]
pub(crate) enum FlagFileError {
    #[error("--config needs a file")]
    Missing,
    #[error("cannot read {path}: {why}")]
    Read { path: String, why: String },
    #[error("{path}: {why}")]
    Toml { path: String, why: String },
    #[error("{path}: '{key}' is not an option of `vl {command}` (see vl {command} --help)")]
    Unknown {
        path: String,
        key: String,
        command: String,
    },
    #[error("{path}: '{key}': {why}")]
    Value {
        path: String,
        key: String,
        why: String,
    },
}

/// `args` (a whole command line) with the flags of the file given to
/// `subcommand` by `--config FILE` put in right after it; `args` as they
/// are without one.
pub(crate) fn with_flag_file(
    args: Vec<OsString>,
    cli: &clap::Command,
    subcommand: &str,
) -> Result<Vec<OsString>, FlagFileError> {
    // The subcommand comes first: the program takes no options before it.
    let at = 1;
    if args.get(at).is_none_or(|a| a != subcommand) {
        return Ok(args);
    }
    let Some(command) = cli.find_subcommand(subcommand) else {
        return Ok(args);
    };
    let given = args[at + 1..].iter().enumerate().find_map(|(i, a)| {
        let a = a.to_str()?;
        match a.strip_prefix("--config=") {
            Some(file) => Some(Some(file.to_owned())),
            None if a == FLAG => Some(
                args.get(at + 2 + i)
                    .and_then(|f| f.to_str())
                    .map(str::to_owned),
            ),
            None => None,
        }
    });
    let Some(file) = given else {
        return Ok(args);
    };
    let file = file.ok_or(FlagFileError::Missing)?;
    let flags = flags(command, Path::new(&file))?;
    let mut out = args[..=at].to_vec();
    out.extend(flags);
    out.extend(args[at + 1..].iter().cloned());
    Ok(out)
}

/// The flags `path` holds for `command`.
fn flags(command: &clap::Command, path: &Path) -> Result<Vec<OsString>, FlagFileError> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| FlagFileError::Read {
        path: shown.clone(),
        why: e.to_string(),
    })?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| FlagFileError::Toml {
        path: shown.clone(),
        why: e.message().to_owned(),
    })?;
    let folder = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (key, value) in &table {
        let arg = command
            .get_arguments()
            .find(|a| a.get_long() == Some(key.as_str()) && key != "config")
            .ok_or_else(|| FlagFileError::Unknown {
                path: shown.clone(),
                key: key.clone(),
                command: command.get_name().to_owned(),
            })?;
        let bad = |why: &str| FlagFileError::Value {
            path: shown.clone(),
            key: key.clone(),
            why: why.to_owned(),
        };
        let switch = !arg.get_action().takes_values();
        let text = match value {
            toml::Value::Boolean(on) if switch => {
                if *on {
                    out.push(format!("--{key}").into());
                }
                continue;
            }
            _ if switch => return Err(bad("a switch is true or false")),
            toml::Value::String(s) => s.clone(),
            toml::Value::Integer(n) => n.to_string(),
            toml::Value::Float(x) => x.to_string(),
            toml::Value::Array(items) => items
                .iter()
                .map(|v| match v {
                    toml::Value::String(s) => Ok(s.clone()),
                    _ => Err(bad("a list holds strings")),
                })
                .collect::<Result<Vec<_>, _>>()?
                .join(","),
            // A table (`[rubric]`) is its flag's TOML text.
            toml::Value::Table(table) => toml::to_string(table).map_err(|e| bad(&e.to_string()))?,
            _ => return Err(bad("a value is a string, a number or a list of strings")),
        };
        out.push(format!("--{key}").into());
        out.push(located(&text, arg.get_value_hint(), folder));
    }
    Ok(out)
}

/// A path from the flag file, read from its `folder`: always for a file
/// or folder, and for something that may be a path or a name (an arena)
/// only when that path exists.
fn located(value: &str, hint: ValueHint, folder: &Path) -> OsString {
    let path = Path::new(value);
    let there: PathBuf = folder.join(path);
    let is_path = match hint {
        ValueHint::FilePath | ValueHint::DirPath => true,
        ValueHint::AnyPath => there.exists(),
        _ => false,
    };
    if is_path && path.is_relative() {
        there.into()
    } else {
        value.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cli() -> clap::Command {
        clap::Command::new("vl").subcommand(
            clap::Command::new("host")
                .args_override_self(true)
                .arg(clap::arg!(--slot <SPAN>))
                .arg(clap::arg!(--users <FILE>).value_hint(ValueHint::FilePath))
                .arg(clap::arg!(--experiments <LIST>))
                .arg(clap::arg!(--"no-reset"))
                .arg(clap::arg!(--config <FILE>)),
        )
    }

    fn file(text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vl-flag-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!(
            "{:x}.toml",
            text.len() * 31 + text.as_bytes()[0] as usize
        ));
        std::fs::write(&path, text).unwrap();
        path
    }

    fn args(line: &[&str]) -> Vec<OsString> {
        line.iter().map(OsString::from).collect()
    }

    #[test]
    fn the_file_goes_first_paths_from_its_folder_and_the_command_line_wins() {
        let path = file(
            "slot = \"10m\"\nusers = \"users.toml\"\nexperiments = [\"navigation\", \"teleoperation\"]\nno-reset = true\n",
        );
        let config = path.to_str().unwrap();
        let out = with_flag_file(
            args(&["vl", "host", "--config", config, "--slot", "5m"]),
            &cli(),
            "host",
        )
        .unwrap();
        let users = path.parent().unwrap().join("users.toml");
        let expected = args(&[
            "vl",
            "host",
            "--experiments",
            "navigation,teleoperation",
            "--no-reset",
            "--slot",
            "10m",
            "--users",
            users.to_str().unwrap(),
            "--config",
            config,
            "--slot",
            "5m",
        ]);
        assert_eq!(out, expected);
        let matches = cli().try_get_matches_from(out).unwrap();
        let host = matches.subcommand_matches("host").unwrap();
        assert_eq!(host.get_one::<String>("slot").unwrap(), "5m");
    }

    #[test]
    fn what_is_not_an_option_is_named() {
        let path = file("slots = \"10m\"\n");
        let line = args(&["vl", "host", &format!("--config={}", path.display())]);
        let e = with_flag_file(line, &cli(), "host").unwrap_err();
        assert!(
            e.to_string()
                .ends_with("'slots' is not an option of `vl host` (see vl host --help)"),
            "{e}"
        );
        let path = file("no-reset = \"yes\"\n");
        let line = args(&["vl", "host", "--config", path.to_str().unwrap()]);
        let e = with_flag_file(line, &cli(), "host").unwrap_err();
        assert!(
            e.to_string()
                .ends_with("'no-reset': a switch is true or false"),
            "{e}"
        );
        let line = args(&["vl", "host", "--config"]);
        assert_eq!(
            with_flag_file(line, &cli(), "host"),
            Err(FlagFileError::Missing)
        );
        let untouched = args(&["vl", "plan", "--config", "x"]);
        assert_eq!(
            with_flag_file(untouched.clone(), &cli(), "host").unwrap(),
            untouched
        );
    }
}
