//! Deep Linking 2.0: an instructor's choice of what a course's link opens
//! (an experiment, and a goal), answered to the platform as a signed
//! `LtiDeepLinkingResponse` holding one `ltiResourceLink` with a line item
//! graded out of the rubric's maximum. Its custom parameters come back in
//! each launch of the link.

use axum::http::StatusCode;
use serde_json::json;

use super::launch::{Refused, now_s};
use super::{Lti, claim};
use vl_host::AccountRole;

/// What the link opens.
pub(crate) struct Item {
    pub title: String,
    pub experiment: String,
    /// Where the goal is, mm.
    pub goal: Option<(f64, f64)>,
}

impl Lti {
    /// The return URL and the signed answer of the deep-linking request
    /// the session `session` was launched with.
    pub(crate) fn deep_link_response(
        &self,
        session: &str,
        item: &Item,
    ) -> Result<(String, String), Refused> {
        let refused = |status, why: &str| Refused {
            status,
            why: why.to_owned(),
        };
        let launch = self
            .sessions
            .launch(session)
            .filter(|l| l.role == AccountRole::Admin)
            .ok_or_else(|| {
                refused(
                    StatusCode::FORBIDDEN,
                    "this choice answers no instructor's deep-linking launch",
                )
            })?;
        let settings = launch.deep_linking.as_ref().ok_or_else(|| {
            refused(
                StatusCode::BAD_REQUEST,
                "the launch was not a deep-linking request",
            )
        })?;
        if let Err(unknown) = self.experiments.get(&item.experiment) {
            let why = format!("the experiment is one of {}", unknown.known.join(", "));
            return Err(refused(StatusCode::BAD_REQUEST, &why));
        }
        let mut custom = json!({"experiment": item.experiment});
        if let Some((x, y)) = item.goal {
            custom["goal"] = json!(format!("{x:.0},{y:.0}"));
        }
        let now = now_s();
        let mut claims = json!({
            "iss": launch.client_id,
            "aud": [launch.issuer],
            "iat": now,
            "exp": now + 600,
            "nonce": vl_host::secret(),
            (claim::MESSAGE_TYPE): "LtiDeepLinkingResponse",
            (claim::VERSION): "1.3.0",
            (claim::DEPLOYMENT_ID): launch.deployment_id,
            (claim::CONTENT_ITEMS): [{
                "type": "ltiResourceLink",
                "title": item.title,
                "custom": custom,
                "lineItem": {
                    "scoreMaximum": self.grades.maximum(Some(&item.experiment)),
                    "label": item.title,
                    "resourceId": item.experiment,
                },
            }],
        });
        if let Some(data) = &settings.data {
            claims[claim::DATA] = json!(data);
        }
        let jwt = self
            .key
            .sign(&claims)
            .map_err(|e| refused(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()))?;
        Ok((settings.return_url.clone(), jwt))
    }
}
