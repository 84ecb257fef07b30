//! Who may use the lab: accounts kept as Argon2id hashes (`users`), the
//! door every hello passes — passwords, tokens, failures and their limits
//! (`gate`) — and the audit log of who did what (`audit`).

pub(crate) mod audit;
pub(crate) mod gate;
pub(crate) mod users;

use std::path::{Path, PathBuf};

/// Why a secret could not be read from its file.
#[derive(Debug, thiserror::Error)]
pub enum SecretError {
    #[error("cannot read {0}: {1}")]
    Read(PathBuf, std::io::Error),
    #[error("{0} is empty")]
    Empty(PathBuf),
}

/// The first line of `path`: a secret (a token) kept in a file rather
/// than on a command line, where anyone on the machine reads it.
pub fn secret_from_file(path: &Path) -> Result<String, SecretError> {
    let text = std::fs::read_to_string(path).map_err(|e| SecretError::Read(path.into(), e))?;
    let line = text.lines().next().unwrap_or("").trim();
    if line.is_empty() {
        return Err(SecretError::Empty(path.into()));
    }
    Ok(line.to_owned())
}
