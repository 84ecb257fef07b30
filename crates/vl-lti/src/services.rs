//! What the tool asks of a platform over HTTP: its public keys (JWKS, kept
//! and read again when a launch names a key not seen yet), OAuth2 access
//! tokens by a client-credentials grant with a JWT assertion signed by the
//! tool's key, scores posted to a line item (AGS) and the course's members
//! (NRPS). Every call is bounded in time and in the size of its answer.

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Duration;

use serde::Deserialize;
use serde_json::Value;
use tokio::time::Instant;

use super::{Lti, LtiError, Platform};

/// How long a call to a platform may take.
const TIMEOUT: Duration = Duration::from_secs(10);
/// The largest answer read from a platform, bytes.
const MAX_ANSWER: usize = 1 << 20;
/// A platform's keys are fetched again after this long…
const JWKS_LIFETIME: Duration = Duration::from_secs(3600);
/// …or when a launch names an unknown key, but not more often than this.
const JWKS_REFETCH: Duration = Duration::from_secs(10);
/// Members listed from a roster, at most.
pub(super) const MAX_MEMBERS: usize = 5000;

/// The HTTP client for platforms: HTTPS with the system's roots, through
/// ring (the provider the Host's own TLS uses).
pub(super) fn client() -> Result<reqwest::Client, LtiError> {
    let _ = rustls::crypto::ring::default_provider().install_default();
    reqwest::Client::builder()
        .timeout(TIMEOUT)
        .connect_timeout(TIMEOUT)
        .redirect(reqwest::redirect::Policy::none())
        .user_agent(concat!("vl/", env!("CARGO_PKG_VERSION"), " (LTI 1.3 tool)"))
        .build()
        .map_err(|e| LtiError::Platform(format!("no HTTP client: {e}")))
}

/// A platform's key set, when it was fetched.
struct KeySet {
    keys: jsonwebtoken::jwk::JwkSet,
    at: Instant,
}

/// Access tokens by platform and scope, and the key sets by URL.
#[derive(Default)]
pub(super) struct AccessTokens {
    tokens: Mutex<HashMap<(String, String), (String, Instant)>>,
    keys: Mutex<HashMap<String, KeySet>>,
}

#[derive(Deserialize)]
struct TokenAnswer {
    access_token: String,
    #[serde(default)]
    expires_in: Option<u64>,
}

/// `response`'s body as JSON, when it is a success of at most [`MAX_ANSWER`] bytes.
async fn json(what: &str, mut response: reqwest::Response) -> Result<Value, LtiError> {
    let status = response.status();
    let mut body = Vec::new();
    while let Some(chunk) = response
        .chunk()
        .await
        .map_err(|e| LtiError::Platform(format!("{what}: {e}")))?
    {
        if body.len() + chunk.len() > MAX_ANSWER {
            return Err(LtiError::Platform(format!(
                "{what}: answer over {MAX_ANSWER} bytes"
            )));
        }
        body.extend_from_slice(&chunk);
    }
    if !status.is_success() {
        let text: String = String::from_utf8_lossy(&body).chars().take(200).collect();
        return Err(LtiError::Platform(format!("{what}: {status} {text}")));
    }
    if body.is_empty() {
        return Ok(Value::Null);
    }
    serde_json::from_slice(&body).map_err(|e| LtiError::Platform(format!("{what}: not JSON: {e}")))
}

impl Lti {
    /// The key `kid` of `platform` (its only key when no kid is named).
    pub(super) async fn platform_key(
        &self,
        platform: &Platform,
        kid: Option<&str>,
    ) -> Result<jsonwebtoken::DecodingKey, LtiError> {
        let pick = |set: &jsonwebtoken::jwk::JwkSet| match kid {
            Some(kid) => set.find(kid).cloned(),
            None if set.keys.len() == 1 => set.keys.first().cloned(),
            None => None,
        };
        let (known, fetch) = {
            let keys = super::locked(&self.tokens.keys);
            let set = keys.get(&platform.jwks_url);
            let known = set
                .filter(|s| s.at.elapsed() < JWKS_LIFETIME)
                .and_then(|s| pick(&s.keys));
            let fetch = known.is_none() && set.is_none_or(|s| s.at.elapsed() >= JWKS_REFETCH);
            (known, fetch)
        };
        let jwk = match (known, fetch) {
            (Some(jwk), _) => jwk,
            (None, false) => {
                return Err(LtiError::Platform(format!(
                    "no key '{}' in {}",
                    kid.unwrap_or("(none named)"),
                    platform.jwks_url
                )));
            }
            (None, true) => {
                let what = format!("its keys ({})", platform.jwks_url);
                let answer = self.http.get(&platform.jwks_url).send().await;
                let answer = answer.map_err(|e| LtiError::Platform(format!("{what}: {e}")))?;
                let set: jsonwebtoken::jwk::JwkSet =
                    serde_json::from_value(json(&what, answer).await?)
                        .map_err(|e| LtiError::Platform(format!("{what}: not a JWK set: {e}")))?;
                let found = pick(&set);
                super::locked(&self.tokens.keys).insert(
                    platform.jwks_url.clone(),
                    KeySet {
                        keys: set,
                        at: Instant::now(),
                    },
                );
                found.ok_or_else(|| {
                    LtiError::Platform(format!(
                        "{what} hold no key '{}'",
                        kid.unwrap_or("(none named)")
                    ))
                })?
            }
        };
        jsonwebtoken::DecodingKey::from_jwk(&jwk)
            .map_err(|e| LtiError::Platform(format!("its key '{}': {e}", kid.unwrap_or(""))))
    }

    /// An access token of `platform` for `scope`: kept while it lasts,
    /// else asked for with a JWT signed by the tool's key.
    pub(super) async fn access_token(
        &self,
        platform: &Platform,
        scope: &str,
    ) -> Result<String, LtiError> {
        let key = (
            format!("{}\n{}", platform.issuer, platform.client_id),
            scope.to_owned(),
        );
        if let Some((token, until)) = super::locked(&self.tokens.tokens).get(&key)
            && *until > Instant::now()
        {
            return Ok(token.clone());
        }
        let now = super::launch::now_s();
        let assertion = self.key.sign(&serde_json::json!({
            "iss": platform.client_id,
            "sub": platform.client_id,
            "aud": platform.audience.as_deref().unwrap_or(&platform.token_url),
            "iat": now,
            "exp": now + 300,
            "jti": vl_host::secret(),
        }))?;
        let form = [
            ("grant_type", "client_credentials"),
            (
                "client_assertion_type",
                "urn:ietf:params:oauth:client-assertion-type:jwt-bearer",
            ),
            ("client_assertion", assertion.as_str()),
            ("scope", scope),
        ];
        let what = format!("a token ({})", platform.token_url);
        let answer = self
            .http
            .post(&platform.token_url)
            .form(&form)
            .send()
            .await
            .map_err(|e| LtiError::Platform(format!("{what}: {e}")))?;
        let answer: TokenAnswer = serde_json::from_value(json(&what, answer).await?)
            .map_err(|e| LtiError::Platform(format!("{what}: {e}")))?;
        // Kept a minute less than it lasts, so it is never used expired.
        let lasts = Duration::from_secs(answer.expires_in.unwrap_or(3600).clamp(60, 86_400) - 59);
        super::locked(&self.tokens.tokens)
            .insert(key, (answer.access_token.clone(), Instant::now() + lasts));
        Ok(answer.access_token)
    }

    /// Posts `score` (AGS's score JSON) to `lineitem`'s scores.
    pub(super) async fn post_score(
        &self,
        platform: &Platform,
        lineitem: &str,
        score: &Value,
    ) -> Result<(), LtiError> {
        let token = self
            .access_token(platform, super::claim::SCORE_SCOPE)
            .await?;
        let mut url = url::Url::parse(lineitem)
            .map_err(|e| LtiError::Platform(format!("the line item '{lineitem}': {e}")))?;
        let path = format!("{}/scores", url.path().trim_end_matches('/'));
        url.set_path(&path);
        let what = format!("the score ({url})");
        let answer = self
            .http
            .post(url.clone())
            .bearer_auth(token)
            .header(
                reqwest::header::CONTENT_TYPE,
                "application/vnd.ims.lis.v1.score+json",
            )
            .body(score.to_string())
            .send()
            .await
            .map_err(|e| LtiError::Platform(format!("{what}: {e}")))?;
        json(&what, answer).await.map(|_| ())
    }

    /// The members of the course whose roster service is `memberships`.
    pub(super) async fn members(
        &self,
        platform: &Platform,
        memberships: &str,
    ) -> Result<Vec<Value>, LtiError> {
        let token = self
            .access_token(platform, super::claim::ROSTER_SCOPE)
            .await?;
        let what = format!("the roster ({memberships})");
        let answer = self
            .http
            .get(memberships)
            .bearer_auth(token)
            .header(
                reqwest::header::ACCEPT,
                "application/vnd.ims.lti-nrps.v2.membershipcontainer+json",
            )
            .send()
            .await
            .map_err(|e| LtiError::Platform(format!("{what}: {e}")))?;
        let container = json(&what, answer).await?;
        let mut members: Vec<Value> = container
            .get("members")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        members.truncate(MAX_MEMBERS);
        Ok(members)
    }
}
