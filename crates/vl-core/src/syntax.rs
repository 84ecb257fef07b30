//! How positions, shapes and scene events are written on a command line:
//! comma-separated numbers, and what is wrong with text that says none.

use crate::ShapeError;

/// Text that does not say what it should, in words a user can act on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SyntaxError {
    #[error("'{0}' is not a number")]
    NotANumber(String),
    #[error("'{0}' is not a finite number")]
    NotFinite(String),
    /// Text of another form than `expected` says.
    #[error("{expected}, not '{got}'")]
    Form { expected: &'static str, got: String },
    #[error("unknown {kind} '{got}': {expected}")]
    Unknown {
        kind: &'static str,
        got: String,
        expected: &'static str,
    },
    /// A number outside what it may be.
    #[error("'{got}' is not {what}")]
    Range { got: String, what: String },
    #[error(transparent)]
    Shape(#[from] ShapeError),
}

/// Comma-separated finite numbers.
pub(crate) fn parse_numbers(text: &str) -> Result<Vec<f64>, SyntaxError> {
    text.split(',')
        .map(|n| {
            let v: f64 = n
                .trim()
                .parse()
                .map_err(|_| SyntaxError::NotANumber(n.to_owned()))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(SyntaxError::NotFinite(n.to_owned()))
            }
        })
        .collect()
}
