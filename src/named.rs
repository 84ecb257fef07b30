//! `Named` values on a command line: clap's parser for them, which lists
//! the ids in `--help` and, for an id that names nothing, the ids that do
//! and what an old id is called now; and experiments, by id or folder, and
//! what a command's `--experiments` offers.

use std::marker::PhantomData;

use clap::builder::{PossibleValue, TypedValueParser};

#[cfg(feature = "host")]
use std::path::{Path, PathBuf};

#[cfg(feature = "host")]
use anyhow::Result;
use vl_core::{ExperimentId, Experiments, Named};

#[cfg(feature = "host")]
use crate::BadInput;

/// Parses a [`Named`] value by its id, listing the ids in `--help` and in
/// the error for one that names nothing.
#[derive(Clone)]
pub(crate) struct NamedParser<T>(PhantomData<T>);

pub(crate) fn named_parser<T: Named + Send + Sync + Clone>() -> NamedParser<T> {
    NamedParser(PhantomData)
}

impl<T: Named + Send + Sync + Clone> TypedValueParser for NamedParser<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<T, clap::Error> {
        let text = value.to_string_lossy();
        T::from_id(&text).map_err(|e| {
            let known: Vec<String> = e.known.iter().map(|s| s.to_string()).collect();
            unknown(cmd, arg, &e.name, known, e.now)
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::ALL.iter().map(|v| PossibleValue::new(v.id()))))
    }
}

/// Parses an experiment's id, listing the ones vl ships in `--help`:
/// only theirs (`Shipped`, an unknown id refused naming them), or any a
/// Host may offer from a folder (`AnyId`).
#[derive(Clone, Copy)]
pub(crate) enum ExperimentParser {
    #[cfg(all(feature = "guest", feature = "host"))]
    Shipped,
    AnyId,
}

impl TypedValueParser for ExperimentParser {
    type Value = ExperimentId;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<ExperimentId, clap::Error> {
        let text = value.to_string_lossy();
        let shipped = Experiments::shipped();
        match (self, shipped.get(&text)) {
            (_, Ok(offered)) => Ok(offered.experiment().id.clone()),
            (ExperimentParser::AnyId, Err(e)) if e.now.is_none() => ExperimentId::new(&text)
                .map_err(|bad| {
                    clap::Error::raw(clap::error::ErrorKind::InvalidValue, format!("{bad}\n"))
                        .with_cmd(cmd)
                }),
            (_, Err(e)) => Err(unknown(cmd, arg, &e.name, e.known, e.now.as_deref())),
        }
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            Experiments::shipped()
                .experiments()
                .map(|e| PossibleValue::new(e.id.as_str())),
        ))
    }
}

/// clap's error for `name`, which names none of `known`: with what it is
/// called `now`, if it once named one.
fn unknown(
    cmd: &clap::Command,
    arg: Option<&clap::Arg>,
    name: &str,
    known: Vec<String>,
    now: Option<&str>,
) -> clap::Error {
    let mut error = clap::Error::new(clap::error::ErrorKind::InvalidValue).with_cmd(cmd);
    if let Some(arg) = arg {
        error.insert(
            clap::error::ContextKind::InvalidArg,
            clap::error::ContextValue::String(arg.to_string()),
        );
    }
    error.insert(
        clap::error::ContextKind::InvalidValue,
        clap::error::ContextValue::String(name.to_owned()),
    );
    error.insert(
        clap::error::ContextKind::ValidValue,
        clap::error::ContextValue::Strings(known),
    );
    if let Some(now) = now {
        error.insert(
            clap::error::ContextKind::Suggested,
            clap::error::ContextValue::StyledStrs(vec![
                format!("'{name}' is called '{now}' now").into(),
            ]),
        );
    }
    error
}

/// An experiment `--experiments` names: a shipped one (or a folder's) by
/// id, or a folder.
#[cfg(feature = "host")]
#[derive(Debug, Clone)]
pub(crate) enum ExperimentChoice {
    Id(ExperimentId),
    Folder(PathBuf),
}

/// Parses a choice: a folder when it looks like a path or is a directory
/// here, else an id (a shipped one, or a folder's); the shipped ones are
/// listed in `--help`.
#[cfg(feature = "host")]
#[derive(Clone, Copy)]
pub(crate) struct ExperimentChoiceParser;

#[cfg(feature = "host")]
impl TypedValueParser for ExperimentChoiceParser {
    type Value = ExperimentChoice;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<ExperimentChoice, clap::Error> {
        let text = value.to_string_lossy();
        let path = Path::new(value);
        if text.contains(std::path::MAIN_SEPARATOR) || text.starts_with('.') || path.is_dir() {
            return Ok(ExperimentChoice::Folder(path.to_path_buf()));
        }
        ExperimentParser::AnyId
            .parse_ref(cmd, arg, value)
            .map(ExperimentChoice::Id)
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        ExperimentParser::AnyId.possible_values()
    }
}

/// What `--experiments` offers: the shipped experiments and its folders',
/// each verified, then only the ids it names if it names any.
#[cfg(feature = "host")]
pub(crate) fn offered(choices: &[ExperimentChoice]) -> Result<Experiments> {
    let (mut ids, mut folders) = (Vec::new(), Vec::new());
    for choice in choices {
        match choice {
            ExperimentChoice::Id(id) => ids.push(id.clone()),
            ExperimentChoice::Folder(folder) => folders.push(folder.clone()),
        }
    }
    let all = Experiments::shipped()
        .with_folders(&folders)
        .map_err(|e| BadInput(format!("--experiments: {e}")))?;
    if ids.is_empty() {
        return Ok(all);
    }
    all.only(&ids)
        .map_err(|e| BadInput(format!("--experiments: {e}")).into())
}
