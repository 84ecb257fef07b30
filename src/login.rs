//! How a Guest logs in, from the command line, and the secrets flags name:
//! from a file, the environment or a prompt, never the process list.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use vl_client::Login;

use crate::BadInput;

/// How a Guest logs in.
#[derive(clap::Args)]
pub(crate) struct LoginArgs {
    /// Log in with this account; the password comes from VL_PASSWORD or a prompt.
    #[arg(long)]
    user: Option<String>,
    /// The operator token the Host asks for (or VL_TOKEN, or --token-file).
    #[arg(
        long,
        env = "VL_TOKEN",
        hide_env_values = true,
        conflicts_with = "user"
    )]
    token: Option<String>,
    /// A file whose first line is the operator token.
    #[arg(long, conflicts_with_all = ["token", "user"])]
    token_file: Option<PathBuf>,
}

impl LoginArgs {
    pub(crate) fn login(&self) -> Result<Login> {
        if let Some(user) = &self.user {
            return Ok(Login::user(
                user,
                password(&format!("{user}'s password: "))?,
            ));
        }
        Ok(Login::token(match &self.token_file {
            Some(file) => Some(first_line(file)?),
            None => self.token.clone(),
        }))
    }
}

/// A password: VL_PASSWORD when set, else asked for on the terminal.
pub(crate) fn password(prompt: &str) -> Result<String> {
    if let Ok(password) = std::env::var("VL_PASSWORD") {
        return Ok(password);
    }
    rpassword::prompt_password(prompt).context("no password: set VL_PASSWORD or run on a terminal")
}

/// The first line of `path`: a secret (a token) kept in a file rather
/// than on a command line, where anyone on the machine reads it.
pub(crate) fn first_line(path: &Path) -> Result<String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| BadInput(format!("cannot read {}: {e}", path.display())))?;
    let line = text.lines().next().unwrap_or("").trim();
    anyhow::ensure!(
        !line.is_empty(),
        BadInput(format!("{} is empty", path.display()))
    );
    Ok(line.to_owned())
}
