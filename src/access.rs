//! Who may use the lab, from the command line: the Host's accounts, token
//! and audit log (`AccessArgs`), and `vl users`, which keeps the accounts
//! file. Secrets come from a file, the environment or a prompt
//! (`crate::login`), so no other user of the machine reads them in the
//! process list.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::ValueHint;
#[cfg(feature = "lti")]
use vl_core::Rubric;
use vl_host::{AccountRole, Audit, HostConfig, Observers, Tls, Users};
#[cfg(feature = "lti")]
use vl_lti::{Lti, LtiOptions};

use crate::login::{first_line, password};
use crate::report::emit;
use crate::{BadInput, bad_input, named};

/// The Host's door.
#[derive(clap::Args)]
pub(crate) struct AccessArgs {
    /// The lab's accounts (TOML; `vl users add` writes it): operators log in.
    #[arg(long, value_hint = ValueHint::FilePath)]
    users: Option<PathBuf>,
    /// With --users: whether anyone may watch, or only people with an account.
    #[arg(long, value_parser = named::<Observers>(), default_value = "anyone", requires = "users")]
    observers: Observers,
    /// Operators (scripts) may instead present this token; better from
    /// the environment or --token-file than on the command line.
    #[arg(long, env = "VL_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// A file whose first line is the operators' token.
    #[arg(long, conflicts_with = "token", value_hint = ValueHint::FilePath)]
    token_file: Option<PathBuf>,
    /// Append who did what (logins, roles, runs, refusals, faults) to this
    /// file, JSON lines (default with --users: audit.jsonl beside it).
    #[arg(long, value_hint = ValueHint::FilePath)]
    audit: Option<PathBuf>,
    /// Speak only WebSocket over TLS (wss://) with this PEM certificate chain…
    #[arg(long, requires = "tls_key", value_hint = ValueHint::FilePath)]
    tls_cert: Option<PathBuf>,
    /// …and its PEM private key.
    #[arg(long, requires = "tls_cert", value_hint = ValueHint::FilePath)]
    tls_key: Option<PathBuf>,
    /// Or with a certificate signed by itself, made once and kept in vl's
    /// data directory (tls/self-signed.pem): Guests pin it by the
    /// fingerprint in the address the Host prints (#pin=…), the same at
    /// every start.
    #[arg(long, conflicts_with = "tls_cert")]
    tls_self_signed: bool,
    /// With --tls-self-signed: make a new certificate in place of the kept
    /// one (every Guest must then pin the new fingerprint).
    #[arg(long, requires = "tls_self_signed")]
    tls_renew: bool,
    /// Web pages from this origin (https://host[:port]) may open the lab's
    /// WebSocket too, besides the Host's own page: e.g. Foxglove's web app,
    /// https://app.foxglove.dev. Repeat it, or separate with commas.
    #[arg(long, value_delimiter = ',')]
    allow_origin: Vec<String>,
    /// How runs are graded for an LMS the lab is launched from (`vl lti`):
    /// points and bounds, e.g. "goal=60,time_s=90" (a [rubric] table in
    /// --config's file). Unset ones keep their defaults: goal=50,
    /// no_collisions=20, per_collision=10, tracking=10, tracking_mm=10,
    /// time=10, time_s=60, forecast=10, forecast_mm=10.
    #[cfg(feature = "lti")]
    #[arg(long, value_parser = crate::lti::rubric, requires = "users")]
    rubric: Option<Rubric>,
}

fn users_from(path: &Path) -> Result<Users> {
    Users::load(path).map_err(|e| BadInput(e.to_string()).into())
}

impl AccessArgs {
    /// Puts the door these flags describe into `config`.
    pub(crate) fn apply(&self, config: &mut HostConfig) -> Result<()> {
        config.token = match &self.token_file {
            Some(file) => Some(first_line(file)?),
            None => self.token.clone(),
        };
        if let Some(path) = &self.users {
            let users = users_from(path)?;
            #[cfg(feature = "lti")]
            let lms = Lti::registered(path).map_err(bad_input)?;
            #[cfg(not(feature = "lti"))]
            let lms = false;
            anyhow::ensure!(
                !users.is_empty() || lms,
                BadInput(format!(
                    "{} holds no account: add one with vl users add (or register an LMS with vl lti add-platform)",
                    path.display()
                ))
            );
            config.users = Some(users);
            config.observers = self.observers;
        }
        config.tls = match (&self.tls_cert, &self.tls_key) {
            (Some(cert), Some(key)) => Some(Tls::from_files(cert, key)),
            _ if self.tls_self_signed => {
                let dir = vl_record::data_dir()
                    .context("no data directory to keep the certificate in: set HOME")?
                    .join("tls");
                Some(Tls::self_signed_kept(
                    &dir,
                    vec!["localhost".into()],
                    self.tls_renew,
                ))
            }
            _ => None,
        }
        .transpose()
        .map_err(bad_input)?;
        config.allow_origins = vl_host::AllowedOrigins::new(&self.allow_origin)
            .map_err(|e| BadInput(format!("--allow-origin: {e}")))?;
        let audit = self
            .audit
            .clone()
            .or_else(|| self.users.as_ref().map(|u| u.with_file_name("audit.jsonl")));
        if let Some(path) = audit {
            config.audit = Audit::open(&path)
                .with_context(|| format!("cannot open the audit log {}", path.display()))?;
        }
        #[cfg(feature = "lti")]
        self.lms(config)?;
        Ok(())
    }

    /// The LMS side of a lab whose accounts file has a platform beside it.
    #[cfg(feature = "lti")]
    fn lms(&self, config: &mut HostConfig) -> Result<()> {
        if let Some(users) = self
            .users
            .as_ref()
            .filter(|u| Lti::registered(u).unwrap_or(false))
        {
            let options = LtiOptions {
                users: users.clone(),
                rubric: self.rubric,
                experiments: config.experiments.clone(),
            };
            let lti = Lti::new(options, config.audit.clone()).map_err(bad_input)?;
            config.extensions.push(lti);
        }
        Ok(())
    }
}

/// `vl users`: keep a lab's accounts file.
#[derive(clap::Subcommand)]
pub(crate) enum UsersCommand {
    /// Add an account (the password from VL_PASSWORD or a prompt).
    Add {
        file: PathBuf,
        name: String,
        #[arg(long, value_parser = named::<AccountRole>(), default_value = "operator")]
        role: AccountRole,
    },
    /// Remove an account.
    Remove { file: PathBuf, name: String },
    /// Set an account's password (from VL_PASSWORD or a prompt), and its role.
    Passwd {
        file: PathBuf,
        name: String,
        #[arg(long, value_parser = named::<AccountRole>())]
        role: Option<AccountRole>,
    },
    /// List the accounts and their roles.
    List {
        file: PathBuf,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) fn users(command: UsersCommand) -> Result<ExitCode> {
    let (UsersCommand::Add { file, .. }
    | UsersCommand::Remove { file, .. }
    | UsersCommand::Passwd { file, .. }
    | UsersCommand::List { file, .. }) = &command;
    let mut users = users_from(file)?;
    match &command {
        UsersCommand::List { json, .. } => {
            return emit(&users.roster(), *json).map(|()| ExitCode::SUCCESS);
        }
        UsersCommand::Add { name, role, .. } => {
            users.add(name, *role, &password(&format!("{name}'s password: "))?)
        }
        UsersCommand::Remove { name, .. } => users.remove(name),
        UsersCommand::Passwd { name, role, .. } => {
            users.passwd(name, &password(&format!("{name}'s new password: "))?, *role)
        }
    }
    .and_then(|()| users.save(file))
    .map_err(bad_input)?;
    eprintln!("{}: {} accounts", file.display(), users.accounts().len());
    Ok(ExitCode::SUCCESS)
}
