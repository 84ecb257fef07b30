//! `Named` values on a command line: clap's parser for them, which lists
//! the ids in `--help` and, for an id that names nothing, the ids that do
//! and what an old id is called now.

use std::marker::PhantomData;

use clap::builder::{PossibleValue, TypedValueParser};

use vl_core::Named;

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
            let mut error = clap::Error::new(clap::error::ErrorKind::InvalidValue).with_cmd(cmd);
            if let Some(arg) = arg {
                error.insert(
                    clap::error::ContextKind::InvalidArg,
                    clap::error::ContextValue::String(arg.to_string()),
                );
            }
            error.insert(
                clap::error::ContextKind::InvalidValue,
                clap::error::ContextValue::String(text.into_owned()),
            );
            error.insert(
                clap::error::ContextKind::ValidValue,
                clap::error::ContextValue::Strings(e.known.iter().map(|s| s.to_string()).collect()),
            );
            if let Some(now) = e.now {
                error.insert(
                    clap::error::ContextKind::Suggested,
                    clap::error::ContextValue::StyledStrs(vec![
                        format!("'{}' is called '{now}' now", e.name).into(),
                    ]),
                );
            }
            error
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::ALL.iter().map(|v| PossibleValue::new(v.id()))))
    }
}
