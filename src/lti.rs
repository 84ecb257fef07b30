//! `vl lti`: the lab as a tool of a teacher's LMS (LTI 1.3). The LMS
//! administrator registers the tool there with what `tool-config` prints,
//! and the lab's administrator registers the platform here with what the
//! LMS shows (`add-platform`); `vl host --users FILE` then takes launches
//! from it by itself. The rubric runs are graded by is `--rubric` (a
//! `[rubric]` table in `vl host --config lab.toml`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::ValueHint;
use serde::Serialize;
use vl_core::Rubric;
use vl_lti::{Platform, Registry, ToolKey};
use vl_report::table::{Report, Table};

use crate::bad_input;
use crate::report::emit;

#[derive(clap::Subcommand)]
pub(crate) enum LtiCommand {
    /// Register an LMS platform (its values from the LMS's tool page).
    AddPlatform(AddPlatform),
    /// The platforms registered.
    List {
        /// The lab's accounts file: the platforms are kept beside it.
        #[arg(long, value_hint = ValueHint::FilePath)]
        users: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Remove a platform.
    Remove {
        #[arg(long, value_hint = ValueHint::FilePath)]
        users: PathBuf,
        #[arg(long)]
        issuer: String,
        /// Only its registration with this client id.
        #[arg(long)]
        client_id: Option<String>,
    },
    /// What the LMS administrator enters: the tool's URLs and public key.
    ToolConfig {
        #[arg(long, value_hint = ValueHint::FilePath)]
        users: PathBuf,
        /// Where people reach the lab: https://HOST[:PORT] of `vl host`.
        #[arg(long)]
        url: url::Url,
        #[arg(long)]
        json: bool,
    },
}

#[derive(clap::Args)]
pub(crate) struct AddPlatform {
    /// The lab's accounts file: the platforms are kept beside it (FILE with .lti.toml).
    #[arg(long, value_hint = ValueHint::FilePath)]
    users: PathBuf,
    /// The platform's issuer (Moodle: its site URL).
    #[arg(long)]
    issuer: String,
    /// The tool's client id at the platform.
    #[arg(long)]
    client_id: String,
    /// The tool's deployment id there (repeat for more).
    #[arg(long, required = true)]
    deployment_id: Vec<String>,
    /// The platform's authentication request URL (OIDC).
    #[arg(long)]
    auth_url: String,
    /// The platform's access token URL (OAuth2).
    #[arg(long)]
    token_url: String,
    /// The platform's public keyset URL.
    #[arg(long)]
    jwks_url: String,
    /// The audience of token requests, when not the token URL.
    #[arg(long)]
    audience: Option<String>,
}

pub(crate) fn run(command: LtiCommand) -> Result<ExitCode> {
    match command {
        LtiCommand::AddPlatform(add) => {
            let path = vl_lti::registry_path(&add.users);
            let mut registry = Registry::load(&path).map_err(bad_input)?;
            registry
                .add(Platform {
                    issuer: add.issuer,
                    client_id: add.client_id,
                    deployment_ids: add.deployment_id,
                    auth_url: add.auth_url,
                    token_url: add.token_url,
                    jwks_url: add.jwks_url,
                    audience: add.audience,
                })
                .map_err(bad_input)?;
            registry.save(&path).map_err(bad_input)?;
            eprintln!("{}: {} platforms", path.display(), registry.platforms.len());
        }
        LtiCommand::List { users, json } => {
            let registry = Registry::load(&vl_lti::registry_path(&users)).map_err(bad_input)?;
            emit(&registry, json)?;
        }
        LtiCommand::Remove {
            users,
            issuer,
            client_id,
        } => {
            let path = vl_lti::registry_path(&users);
            let mut registry = Registry::load(&path).map_err(bad_input)?;
            registry
                .remove(&issuer, client_id.as_deref())
                .map_err(bad_input)?;
            registry.save(&path).map_err(bad_input)?;
            eprintln!("{}: {} platforms", path.display(), registry.platforms.len());
        }
        LtiCommand::ToolConfig { users, url, json } => {
            let key = ToolKey::load_or_make(&vl_lti::key_path(&users)).map_err(bad_input)?;
            emit(&ToolConfig::new(&url, &key), json)?;
            if !json {
                println!(
                    "\nThe tool's public key, for an LMS that asks for it pasted:\n{}",
                    key.public_pem.trim()
                );
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The tool as an LMS registers it.
#[derive(Serialize)]
struct ToolConfig {
    title: &'static str,
    description: &'static str,
    target_link_uri: String,
    oidc_initiation_url: String,
    redirect_uris: Vec<String>,
    jwks_url: String,
    deep_linking_url: String,
    public_jwk: serde_json::Value,
    public_key: String,
    scopes: [&'static str; 2],
}

impl ToolConfig {
    fn new(base: &url::Url, key: &ToolKey) -> ToolConfig {
        let at = |path: &str| base.join(path).map(String::from).unwrap_or_default();
        ToolConfig {
            title: "vl — the virtual lab",
            description: "A real robot lab over the Internet: plan a path on the camera's view, or drive with force feedback.",
            target_link_uri: at("/lti/launch"),
            oidc_initiation_url: at("/lti/login"),
            redirect_uris: vec![at("/lti/launch")],
            jwks_url: at("/lti/jwks"),
            deep_linking_url: at("/lti/launch"),
            public_jwk: key.jwks()["keys"][0].clone(),
            public_key: key.public_pem.clone(),
            scopes: [
                "https://purl.imsglobal.org/spec/lti-ags/scope/score",
                "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly",
            ],
        }
    }
}

impl Report for ToolConfig {
    fn table(&self) -> Table {
        let mut table = Table::columns(&["LMS field", "value"]);
        let rows = [
            ("Tool name", self.title.to_owned()),
            ("Tool URL", self.target_link_uri.clone()),
            ("LTI version", "LTI 1.3".to_owned()),
            ("Public key type", "Keyset URL".to_owned()),
            ("Public keyset", self.jwks_url.clone()),
            ("Initiate login URL", self.oidc_initiation_url.clone()),
            ("Redirection URI(s)", self.redirect_uris.join(" ")),
            ("Content Selection URL", self.deep_linking_url.clone()),
        ];
        for (field, value) in rows {
            table.row(vec![field.to_owned(), value]);
        }
        table
    }
}

/// A rubric from `--rubric`: TOML (`goal = 50` a line, as a `[rubric]`
/// table in lab.toml gives it) or `key=value` pairs separated by commas.
pub(crate) fn rubric(text: &str) -> Result<Rubric, String> {
    let text = if text.contains('\n') {
        text.to_owned()
    } else {
        text.split(',').collect::<Vec<_>>().join("\n")
    };
    let rubric: Rubric = toml::from_str(&text).map_err(|e| e.message().to_owned())?;
    rubric.checked().map_err(|e| e.to_string())
}
