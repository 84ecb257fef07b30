//! The LMS platforms a lab trusts (`vl lti add-platform`), kept beside its
//! accounts file (`users.toml` → `users.lti.toml`, its owner's only), and
//! the tool's own RSA key pair (`users.lti-key.pem`), made once and kept:
//! platforms check the tool's deep-linking answers and its token requests
//! by its public half, published at `/lti/jwks`.

use std::path::{Path, PathBuf};

use base64::Engine;
use rsa::pkcs8::{DecodePrivateKey, EncodePrivateKey, EncodePublicKey, LineEnding};
use rsa::traits::PublicKeyParts;
use serde::{Deserialize, Serialize};
use sha2::Digest;
use vl_report::table::{Report, Table};

use super::LtiError;

/// Platforms a lab keeps, at most.
const MAX_PLATFORMS: usize = 100;
/// Deployments a platform keeps, at most.
const MAX_DEPLOYMENTS: usize = 100;
/// The tool key's size, bits.
const KEY_BITS: usize = 2048;

/// One LMS as its administrator registered the tool there.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Platform {
    /// The `iss` of its launches.
    pub issuer: String,
    /// The tool's client id there: the `aud` of its launches.
    pub client_id: String,
    /// The deployments of the tool there: a launch names one of them.
    pub deployment_ids: Vec<String>,
    /// Where a login is sent on (OIDC authorization endpoint).
    pub auth_url: String,
    /// Where the tool gets tokens for grades and the roster (OAuth2).
    pub token_url: String,
    /// The platform's public keys.
    pub jwks_url: String,
    /// The `aud` of the tool's token requests, when not the token URL.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub audience: Option<String>,
}

impl Platform {
    /// The origins a page of this platform's may frame the lab from.
    pub(crate) fn origins(&self) -> Vec<String> {
        [&self.issuer, &self.auth_url]
            .iter()
            .filter_map(|u| url::Url::parse(u).ok())
            .map(|u| u.origin().ascii_serialization())
            .filter(|o| o != "null")
            .collect()
    }

    fn check(&self) -> Result<(), LtiError> {
        for (what, value) in [
            ("--issuer", &self.issuer),
            ("--auth-url", &self.auth_url),
            ("--token-url", &self.token_url),
            ("--jwks-url", &self.jwks_url),
        ] {
            let url = url::Url::parse(value)
                .map_err(|e| LtiError::Registration(format!("{what} '{value}': {e}")))?;
            if !matches!(url.scheme(), "https" | "http") {
                return Err(LtiError::Registration(format!(
                    "{what} '{value}' is not an http(s) address"
                )));
            }
        }
        if self.client_id.is_empty() || self.client_id.len() > 255 {
            return Err(LtiError::Registration(
                "--client-id is 1 to 255 characters".into(),
            ));
        }
        if self.deployment_ids.is_empty()
            || self.deployment_ids.len() > MAX_DEPLOYMENTS
            || self
                .deployment_ids
                .iter()
                .any(|d| d.is_empty() || d.len() > 255)
        {
            return Err(LtiError::Registration(format!(
                "a platform has 1 to {MAX_DEPLOYMENTS} deployment ids of 1 to 255 characters"
            )));
        }
        Ok(())
    }
}

/// The platforms, as their file keeps them.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Registry {
    #[serde(default, rename = "platform")]
    pub platforms: Vec<Platform>,
}

/// Where the platforms of the lab whose accounts are in `users` are kept.
pub fn registry_path(users: &Path) -> PathBuf {
    users.with_extension("lti.toml")
}

/// Where the tool's key pair of that lab is kept.
pub fn key_path(users: &Path) -> PathBuf {
    users.with_extension("lti-key.pem")
}

impl Registry {
    /// The platforms in `path`; none when the file is not there.
    pub fn load(path: &Path) -> Result<Registry, LtiError> {
        let text = match std::fs::read_to_string(path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Registry::default()),
            Err(e) => return Err(LtiError::File(path.into(), e.to_string())),
        };
        let registry: Registry =
            toml::from_str(&text).map_err(|e| LtiError::File(path.into(), e.to_string()))?;
        if registry.platforms.len() > MAX_PLATFORMS {
            return Err(LtiError::File(
                path.into(),
                format!("more than {MAX_PLATFORMS} platforms"),
            ));
        }
        for platform in &registry.platforms {
            platform
                .check()
                .map_err(|e| LtiError::File(path.into(), e.to_string()))?;
        }
        Ok(registry)
    }

    pub fn save(&self, path: &Path) -> Result<(), LtiError> {
        let text = toml::to_string(self).map_err(|e| LtiError::File(path.into(), e.to_string()))?;
        vl_host::write_private(path, text.as_bytes())
            .map_err(|e| LtiError::File(path.into(), e.to_string()))
    }

    /// Registers `platform`; one already there with its issuer and client
    /// id gains its deployments (an LMS deploys a tool more than once).
    pub fn add(&mut self, platform: Platform) -> Result<(), LtiError> {
        platform.check()?;
        let known = self
            .platforms
            .iter()
            .position(|p| p.issuer == platform.issuer && p.client_id == platform.client_id);
        match known {
            Some(at) => {
                let known = &mut self.platforms[at];
                for id in platform.deployment_ids {
                    if !known.deployment_ids.contains(&id) {
                        known.deployment_ids.push(id);
                    }
                }
                known.auth_url = platform.auth_url;
                known.token_url = platform.token_url;
                known.jwks_url = platform.jwks_url;
                known.audience = platform.audience;
                known.check()
            }
            None if self.platforms.len() >= MAX_PLATFORMS => Err(LtiError::Registration(format!(
                "a lab keeps at most {MAX_PLATFORMS} platforms"
            ))),
            None => {
                self.platforms.push(platform);
                Ok(())
            }
        }
    }

    /// Removes the platforms of `issuer` (only the one with `client_id`, if given).
    pub fn remove(&mut self, issuer: &str, client_id: Option<&str>) -> Result<(), LtiError> {
        let before = self.platforms.len();
        self.platforms
            .retain(|p| p.issuer != issuer || client_id.is_some_and(|c| c != p.client_id));
        if self.platforms.len() == before {
            return Err(LtiError::Registration(format!(
                "no platform '{issuer}' is registered"
            )));
        }
        Ok(())
    }

    /// The platform of a login or launch: by issuer, and client id when
    /// given (needed when one issuer has the tool twice).
    pub(crate) fn find(&self, issuer: &str, client_id: Option<&str>) -> Option<&Platform> {
        let mut found = self
            .platforms
            .iter()
            .filter(|p| p.issuer == issuer && client_id.is_none_or(|c| c == p.client_id));
        let first = found.next()?;
        found.next().is_none().then_some(first)
    }
}

impl Report for Registry {
    fn table(&self) -> Table {
        let mut table = Table::columns(&["issuer", "client id", "deployments", "token URL"]);
        for p in &self.platforms {
            table.row(vec![
                p.issuer.clone(),
                p.client_id.clone(),
                p.deployment_ids.join(", "),
                p.token_url.clone(),
            ]);
        }
        table
    }
}

/// The tool's key pair and how platforms name it.
pub struct ToolKey {
    /// PKCS#8 PEM of the private key, for signing.
    private_pem: String,
    /// SPKI PEM of the public key, for an administrator to paste.
    pub public_pem: String,
    /// The key's id: the start of the SHA-256 of its modulus.
    pub kid: String,
    /// The public key as a JWK (`n`, `e` base64url).
    n: String,
    e: String,
}

impl ToolKey {
    /// The key at `path`, made (2048-bit RSA) and kept there if there is none.
    pub fn load_or_make(path: &Path) -> Result<ToolKey, LtiError> {
        let file = |e: String| LtiError::File(path.into(), e);
        let key = match std::fs::read_to_string(path) {
            Ok(pem) => rsa::RsaPrivateKey::from_pkcs8_pem(&pem).map_err(|e| file(e.to_string()))?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let key = rsa::RsaPrivateKey::new(&mut rsa::rand_core::OsRng, KEY_BITS)
                    .map_err(|e| file(e.to_string()))?;
                let pem = key
                    .to_pkcs8_pem(LineEnding::LF)
                    .map_err(|e| file(e.to_string()))?;
                vl_host::write_private(path, pem.as_bytes()).map_err(|e| file(e.to_string()))?;
                key
            }
            Err(e) => return Err(file(e.to_string())),
        };
        let private_pem = key
            .to_pkcs8_pem(LineEnding::LF)
            .map_err(|e| file(e.to_string()))?
            .to_string();
        let public = key.to_public_key();
        let public_pem = public
            .to_public_key_pem(LineEnding::LF)
            .map_err(|e| file(e.to_string()))?;
        let b64 = base64::engine::general_purpose::URL_SAFE_NO_PAD;
        let n = public.n().to_bytes_be();
        let digest = sha2::Sha256::digest(&n);
        Ok(ToolKey {
            private_pem,
            public_pem,
            kid: digest[..8].iter().map(|b| format!("{b:02x}")).collect(),
            n: b64.encode(&n),
            e: b64.encode(public.e().to_bytes_be()),
        })
    }

    /// The public key as a JWK set, as `/lti/jwks` serves it.
    pub fn jwks(&self) -> serde_json::Value {
        serde_json::json!({"keys": [{
            "kty": "RSA", "alg": "RS256", "use": "sig",
            "kid": self.kid, "n": self.n, "e": self.e,
        }]})
    }

    /// Signs `claims` as a JWT (RS256, with the key's id).
    pub(crate) fn sign(&self, claims: &serde_json::Value) -> Result<String, LtiError> {
        let key = jsonwebtoken::EncodingKey::from_rsa_pem(self.private_pem.as_bytes())
            .map_err(|e| LtiError::Sign(e.to_string()))?;
        let mut header = jsonwebtoken::Header::new(jsonwebtoken::Algorithm::RS256);
        header.kid = Some(self.kid.clone());
        jsonwebtoken::encode(&header, claims, &key).map_err(|e| LtiError::Sign(e.to_string()))
    }
}
