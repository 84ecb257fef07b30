//! An LMS launch, as LTI 1.3 (on OpenID Connect's implicit flow) has it:
//! the platform starts a login at `/lti/login`; the tool sends the browser
//! to the platform's authorization URL with a fresh `state` and `nonce`;
//! the platform posts back a signed `id_token` to `/lti/launch`. The token
//! counts only when its RS256 signature is the platform's (its JWKS), it
//! names this platform, this tool and a registered deployment, it has not
//! expired, its nonce is the login's and unused, and it is an LTI 1.3
//! message the tool takes. Anything else is refused, with why.

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Duration;

use axum::http::StatusCode;
use serde::Deserialize;
use serde_json::Value;
use tokio::time::Instant;

use super::sessions::{Assignment, DeepLinking, Launch};
use super::{Lti, Platform, claim};
use vl_host::AccountRole;

/// Logins waiting for their launch, at most; the oldest go first.
const MAX_PENDING: usize = 10_000;
/// How long a login waits for its launch.
const LOGIN_LIFETIME: Duration = Duration::from_secs(300);
/// Nonces remembered as used, at most.
const MAX_NONCES: usize = 100_000;
/// How far a platform's clock may be ahead of the lab's, s.
const LEEWAY_S: u64 = 60;
/// The longest id token read, bytes.
pub(super) const MAX_ID_TOKEN: usize = 64 << 10;

/// Why a login or launch was refused: the answer's status and the words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Refused {
    pub status: StatusCode,
    pub why: String,
}

fn refused(status: StatusCode, why: impl Into<String>) -> Refused {
    Refused {
        status,
        why: why.into(),
    }
}

fn bad(why: impl Into<String>) -> Refused {
    refused(StatusCode::BAD_REQUEST, why)
}

fn forbidden(why: impl Into<String>) -> Refused {
    refused(StatusCode::FORBIDDEN, why)
}

/// A third-party login initiation, GET's query or POST's form.
#[derive(Debug, Deserialize)]
pub(crate) struct LoginRequest {
    pub iss: String,
    pub login_hint: String,
    pub target_link_uri: String,
    #[serde(default)]
    pub lti_message_hint: Option<String>,
    #[serde(default)]
    pub client_id: Option<String>,
    #[serde(default)]
    pub lti_deployment_id: Option<String>,
}

struct Pending {
    issuer: String,
    client_id: String,
    nonce: String,
    at: Instant,
}

/// Logins under way, and the nonces launches have used.
#[derive(Default)]
pub(super) struct Logins {
    pending: Mutex<HashMap<String, Pending>>,
    /// Each used nonce, and when its token expires (then it may be forgotten).
    used: Mutex<HashMap<String, u64>>,
}

/// A launch that counts: the person's session and what it said.
pub(crate) struct Launched {
    pub session: String,
    pub launch: std::sync::Arc<Launch>,
}

pub(super) fn now_s() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

fn text(claims: &Value, name: &str) -> Option<String> {
    claims.get(name).and_then(Value::as_str).map(str::to_owned)
}

/// The name of a course's (context) role: `Learner` of
/// `http://purl.imsglobal.org/vocab/lis/v2/membership#Learner`, or the
/// simple name LTI 1.3 still allows for one. None for an institution's or
/// the system's role (`…/institution/person#Instructor`): those say what
/// someone is elsewhere, not in this course, so they give no lab role.
pub(super) fn context_role(role: &str) -> Option<&str> {
    const CONTEXT: &str = "http://purl.imsglobal.org/vocab/lis/v2/membership#";
    match role.strip_prefix(CONTEXT) {
        Some(name) => Some(name),
        None if !role.contains(['/', '#', ':']) => Some(role),
        None => None,
    }
}

/// The lab's role for an LMS person, from their course roles only:
/// instructors and administrators run the lab, learners drive in their
/// turn, anyone else watches.
pub(super) fn role_of(roles: &[String]) -> AccountRole {
    let names: Vec<String> = roles
        .iter()
        .filter_map(|r| context_role(r))
        .map(str::to_ascii_lowercase)
        .collect();
    if names
        .iter()
        .any(|n| n == "instructor" || n == "administrator")
    {
        AccountRole::Admin
    } else if names.iter().any(|n| n == "learner") {
        AccountRole::Operator
    } else {
        AccountRole::Observer
    }
}

/// `sub@host`: who an LMS person is at the lab, in printable characters.
pub(super) fn user_name(sub: &str, platform: &Platform) -> String {
    let host = url::Url::parse(&platform.issuer)
        .ok()
        .and_then(|u| u.host_str().map(str::to_owned))
        .unwrap_or_else(|| "lms".into());
    let sub: String = sub
        .chars()
        .filter(|c| c.is_ascii_graphic())
        .take(128)
        .collect();
    format!("{sub}@{host}")
}

impl Lti {
    /// Starts a login: where to send the browser (the platform's
    /// authorization URL, with this login's state and nonce).
    pub(crate) fn login(&self, request: &LoginRequest) -> Result<(String, String), Refused> {
        let registry = self
            .platforms()
            .map_err(|e| refused(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
        let platform = registry
            .find(&request.iss, request.client_id.as_deref())
            .ok_or_else(|| {
                forbidden(format!(
                    "the platform '{}' is not registered at this lab (vl lti add-platform)",
                    request.iss
                ))
            })?;
        if let Some(deployment) = &request.lti_deployment_id
            && !platform.deployment_ids.contains(deployment)
        {
            return Err(forbidden(format!(
                "the deployment '{deployment}' is not registered for this platform"
            )));
        }
        let target = url::Url::parse(&request.target_link_uri)
            .map_err(|e| bad(format!("target_link_uri: {e}")))?;
        if target.path() != "/lti/launch" {
            return Err(bad(
                "target_link_uri is not this tool's launch URL (/lti/launch)",
            ));
        }
        let (state, nonce) = (vl_host::secret(), vl_host::secret());
        let mut auth = url::Url::parse(&platform.auth_url)
            .map_err(|e| refused(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
        {
            let mut query = auth.query_pairs_mut();
            query
                .append_pair("scope", "openid")
                .append_pair("response_type", "id_token")
                .append_pair("response_mode", "form_post")
                .append_pair("prompt", "none")
                .append_pair("client_id", &platform.client_id)
                .append_pair("redirect_uri", target.as_str())
                .append_pair("login_hint", &request.login_hint)
                .append_pair("state", &state)
                .append_pair("nonce", &nonce);
            if let Some(hint) = &request.lti_message_hint {
                query.append_pair("lti_message_hint", hint);
            }
        }
        let mut pending = super::locked(&self.logins.pending);
        pending.retain(|_, p| p.at.elapsed() < LOGIN_LIFETIME);
        let login = Pending {
            issuer: platform.issuer.clone(),
            client_id: platform.client_id.clone(),
            nonce,
            at: Instant::now(),
        };
        super::insert_bounded(&mut pending, MAX_PENDING, state.clone(), login, |p| p.at);
        drop(pending);
        Ok((auth.into(), state))
    }

    /// Checks a launch's `id_token` against the login `state` it answers.
    pub(crate) async fn launch(&self, id_token: &str, state: &str) -> Result<Launched, Refused> {
        let pending = super::locked(&self.logins.pending)
            .remove(state)
            .filter(|p| p.at.elapsed() < LOGIN_LIFETIME)
            .ok_or_else(|| {
                bad("this launch answers no login under way here (unknown, used or expired state): launch the lab again from the course")
            })?;
        let registry = self
            .platforms()
            .map_err(|e| refused(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
        let platform = registry
            .find(&pending.issuer, Some(&pending.client_id))
            .ok_or_else(|| forbidden("the platform was removed during the login"))?;
        let claims = self.verified(id_token, platform).await?;
        self.check_nonce(&claims, &pending.nonce)?;
        let mut launch = checked_launch(&claims, platform)?;
        if text(&claims, claim::MESSAGE_TYPE).as_deref() == Some("LtiDeepLinkingRequest") {
            launch.deep_linking = Some(deep_linking(&claims, &launch)?);
        }
        let session = self.sessions.open(launch);
        let launch = self
            .sessions
            .launch(&session)
            .ok_or_else(|| refused(StatusCode::SERVICE_UNAVAILABLE, "the session did not open"))?;
        Ok(Launched { session, launch })
    }

    /// The token's claims, when it is signed by `platform` for this tool
    /// and has not expired.
    async fn verified(&self, id_token: &str, platform: &Platform) -> Result<Value, Refused> {
        if id_token.len() > MAX_ID_TOKEN {
            return Err(bad("the id_token is too long"));
        }
        let header = jsonwebtoken::decode_header(id_token)
            .map_err(|e| bad(format!("the id_token is not a JWT: {e}")))?;
        if header.alg != jsonwebtoken::Algorithm::RS256 {
            return Err(bad(format!(
                "the id_token is signed with {:?}; LTI 1.3 signs with RS256",
                header.alg
            )));
        }
        let key = self
            .platform_key(platform, header.kid.as_deref())
            .await
            .map_err(|e| refused(StatusCode::BAD_GATEWAY, e.to_string()))?;
        let mut validation = jsonwebtoken::Validation::new(jsonwebtoken::Algorithm::RS256);
        validation.set_issuer(&[&platform.issuer]);
        validation.set_audience(&[&platform.client_id]);
        validation.set_required_spec_claims(&["exp", "iat", "iss", "aud"]);
        validation.leeway = LEEWAY_S;
        let data = jsonwebtoken::decode::<Value>(id_token, &key, &validation)
            .map_err(|e| forbidden(format!("the id_token does not hold: {e}")))?;
        let claims = data.claims;
        let iat = claims.get("iat").and_then(Value::as_u64).unwrap_or(0);
        if iat > now_s() + LEEWAY_S {
            return Err(forbidden("the id_token was issued in the future (iat)"));
        }
        let audiences = match claims.get("aud") {
            Some(Value::Array(a)) => a.len(),
            _ => 1,
        };
        match text(&claims, "azp") {
            Some(azp) if azp != platform.client_id => {
                return Err(forbidden("the id_token's azp is not this tool's client id"));
            }
            None if audiences > 1 => {
                return Err(forbidden("an id_token for several audiences needs azp"));
            }
            _ => {}
        }
        Ok(claims)
    }

    /// Whether the token carries the login's nonce, used for the first time.
    fn check_nonce(&self, claims: &Value, expected: &str) -> Result<(), Refused> {
        let nonce = text(claims, "nonce").ok_or_else(|| forbidden("the id_token has no nonce"))?;
        let mut used = super::locked(&self.logins.used);
        if used.contains_key(&nonce) {
            return Err(forbidden(
                "the id_token's nonce was used before: a replayed launch",
            ));
        }
        if nonce != expected {
            return Err(forbidden("the id_token's nonce is not its login's"));
        }
        let now = now_s();
        if used.len() >= MAX_NONCES {
            used.retain(|_, exp| *exp + LEEWAY_S > now);
        }
        if used.len() >= MAX_NONCES {
            used.clear();
        }
        let exp = claims.get("exp").and_then(Value::as_u64).unwrap_or(now);
        used.insert(nonce, exp);
        Ok(())
    }
}

/// What a verified token says, when it is a launch this tool takes.
fn checked_launch(claims: &Value, platform: &Platform) -> Result<Launch, Refused> {
    let version = text(claims, claim::VERSION);
    if version.as_deref() != Some("1.3.0") {
        return Err(bad(format!(
            "the launch's LTI version is {}, not 1.3.0",
            version.as_deref().unwrap_or("missing")
        )));
    }
    let message = text(claims, claim::MESSAGE_TYPE).unwrap_or_default();
    if !matches!(
        message.as_str(),
        "LtiResourceLinkRequest" | "LtiDeepLinkingRequest"
    ) {
        return Err(bad(format!(
            "the tool takes resource-link and deep-linking launches, not '{message}'"
        )));
    }
    let deployment = text(claims, claim::DEPLOYMENT_ID).unwrap_or_default();
    if !platform.deployment_ids.contains(&deployment) {
        return Err(forbidden(format!(
            "the deployment '{deployment}' is not registered for this platform"
        )));
    }
    let sub = text(claims, "sub")
        .filter(|s| !s.is_empty() && s.len() <= 255)
        .ok_or_else(|| bad("the launch names no person (sub)"))?;
    let roles: Vec<String> = claims
        .get(claim::ROLES)
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(Value::as_str)
                .map(str::to_owned)
                .collect()
        })
        .unwrap_or_default();
    let ags = claims.get(claim::AGS);
    let may_score = ags
        .and_then(|a| a.get("scope"))
        .and_then(Value::as_array)
        .is_some_and(|s| s.iter().any(|s| s.as_str() == Some(claim::SCORE_SCOPE)));
    let custom = claims.get(claim::CUSTOM);
    let custom_text = |name: &str| {
        custom
            .and_then(|c| c.get(name))
            .and_then(Value::as_str)
            .map(|s| s.chars().take(64).collect())
    };
    Ok(Launch {
        issuer: platform.issuer.clone(),
        client_id: platform.client_id.clone(),
        deployment_id: deployment,
        user: user_name(&sub, platform),
        sub,
        person: text(claims, "name").map(|n| n.chars().take(128).collect()),
        role: role_of(&roles),
        course: claims
            .get(claim::CONTEXT)
            .and_then(|c| c.get("title"))
            .and_then(Value::as_str)
            .map(|t| t.chars().take(128).collect()),
        lineitem: ags
            .and_then(|a| a.get("lineitem"))
            .and_then(Value::as_str)
            .filter(|_| may_score)
            .map(str::to_owned),
        memberships: claims
            .get(claim::NRPS)
            .and_then(|n| n.get("context_memberships_url"))
            .and_then(Value::as_str)
            .map(str::to_owned),
        assignment: Assignment {
            experiment: custom_text("experiment"),
            goal: custom_text("goal"),
        },
        deep_linking: None,
    })
}

/// A deep-linking request's settings, for an instructor only.
fn deep_linking(claims: &Value, launch: &Launch) -> Result<DeepLinking, Refused> {
    if launch.role != AccountRole::Admin {
        return Err(forbidden(
            "only the course's instructors choose what a link opens (deep linking)",
        ));
    }
    let settings = claims
        .get(claim::DEEP_LINKING)
        .ok_or_else(|| bad("a deep-linking request without its settings"))?;
    let return_url = settings
        .get("deep_link_return_url")
        .and_then(Value::as_str)
        .filter(|u| url::Url::parse(u).is_ok())
        .ok_or_else(|| bad("the deep-linking settings have no deep_link_return_url"))?;
    let accepts = settings
        .get("accept_types")
        .and_then(Value::as_array)
        .is_some_and(|t| t.iter().any(|t| t.as_str() == Some("ltiResourceLink")));
    if !accepts {
        return Err(bad("the platform does not accept an ltiResourceLink here"));
    }
    Ok(DeepLinking {
        return_url: return_url.to_owned(),
        data: settings
            .get("data")
            .and_then(Value::as_str)
            .map(str::to_owned),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lms_roles_are_the_lab_s() {
        let role = |r: &[&str]| role_of(&r.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>());
        assert_eq!(
            role(&["http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"]),
            AccountRole::Operator
        );
        assert_eq!(
            role(&[
                "http://purl.imsglobal.org/vocab/lis/v2/membership#Learner",
                "http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"
            ]),
            AccountRole::Admin
        );
        // An institution's roles are not the course's.
        assert_eq!(
            role(&["http://purl.imsglobal.org/vocab/lis/v2/institution/person#Administrator"]),
            AccountRole::Observer
        );
        assert_eq!(
            role(&[
                "http://purl.imsglobal.org/vocab/lis/v2/membership#Learner",
                "http://purl.imsglobal.org/vocab/lis/v2/institution/person#Instructor"
            ]),
            AccountRole::Operator
        );
        assert_eq!(role(&["Instructor"]), AccountRole::Admin);
        assert_eq!(
            role(&["http://purl.imsglobal.org/vocab/lis/v2/membership#Mentor"]),
            AccountRole::Observer
        );
        assert_eq!(role(&[]), AccountRole::Observer);
    }
}
