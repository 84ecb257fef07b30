//! The launch check against what anyone may post: whatever the id token,
//! a launch without the platform's signature opens no session and never
//! panics; a login is for registered platforms and this tool's launch URL.

use std::sync::Arc;

use proptest::prelude::*;

use super::launch::LoginRequest;
use super::{Lti, LtiOptions, Platform, Registry, registry_path};
use vl_host::Audit;

/// A lab registered with a platform whose keys cannot be fetched (port 9
/// answers nothing): no token can be proved.
fn lab(name: &str) -> Arc<Lti> {
    let dir = std::env::temp_dir().join(format!("vl-lti-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let users = dir.join("users.toml");
    let mut registry = Registry::default();
    registry
        .add(Platform {
            issuer: "https://lms.example.edu".into(),
            client_id: "c1".into(),
            deployment_ids: vec!["d1".into()],
            auth_url: "https://lms.example.edu/auth".into(),
            token_url: "https://lms.example.edu/token".into(),
            jwks_url: "http://127.0.0.1:9/jwks".into(),
            audience: None,
        })
        .unwrap();
    registry.save(&registry_path(&users)).unwrap();
    let options = LtiOptions {
        users,
        rubric: None,
        experiments: vl_core::Experiments::shipped().clone(),
    };
    Lti::new(options, Audit::default()).unwrap()
}

fn login(issuer: &str, target: &str) -> LoginRequest {
    LoginRequest {
        iss: issuer.into(),
        login_hint: "h".into(),
        target_link_uri: target.into(),
        lti_message_hint: None,
        client_id: None,
        lti_deployment_id: None,
    }
}

#[test]
fn a_login_is_for_a_registered_platform_and_this_tool() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let _in = rt.enter();
    let lti = lab("login");
    let stranger = lti.login(&login("https://stranger.example", "https://lab/lti/launch"));
    assert_eq!(stranger.unwrap_err().status.as_u16(), 403);
    let elsewhere = lti.login(&login(
        "https://lms.example.edu",
        "https://evil.example/steal",
    ));
    assert_eq!(elsewhere.unwrap_err().status.as_u16(), 400);
    let (to, state) = lti
        .login(&login("https://lms.example.edu", "https://lab/lti/launch"))
        .unwrap();
    let to = url::Url::parse(&to).unwrap();
    let query: std::collections::HashMap<_, _> = to.query_pairs().into_owned().collect();
    assert_eq!(to.path(), "/auth");
    assert_eq!(query["state"], state);
    assert_eq!(query["redirect_uri"], "https://lab/lti/launch");
    assert_eq!(query["response_mode"], "form_post");
    assert!(query["nonce"].len() >= 40, "a nonce of 32 random bytes");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn no_unsigned_launch_opens_a_session(token in prop_oneof![
        ".{0,300}",
        "[A-Za-z0-9_-]{1,80}\\.[A-Za-z0-9_-]{1,200}\\.[A-Za-z0-9_-]{0,80}",
        Just("eyJhbGciOiJub25lIn0.eyJzdWIiOiJ4In0.".to_owned()),
        Just("eyJhbGciOiJIUzI1NiJ9.eyJzdWIiOiJ4In0.c2lnbmF0dXJl".to_owned()),
    ]) {
        let rt = tokio::runtime::Runtime::new().unwrap();
        let _in = rt.enter();
        let lti = lab("garbage");
        let (_, state) = lti
            .login(&login("https://lms.example.edu", "https://lab/lti/launch"))
            .unwrap();
        let refused = rt.block_on(lti.launch(&token, &state)).err();
        let refused = refused.expect("refused");
        prop_assert!(refused.status.is_client_error() || refused.status.as_u16() == 502, "{refused:?}");
        prop_assert!(lti.sessions.open_count() == 0);
        // The login it answered is over, whatever came.
        let again = rt.block_on(lti.launch(&token, &state)).err().expect("refused");
        prop_assert_eq!(again.status.as_u16(), 400);
    }
}
