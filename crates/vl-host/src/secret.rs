//! Every secret the lab hands out — a resume secret, an LMS session, a
//! login's state and nonce, a token request's id — drawn in one place.

use base64::Engine;

/// 32 bytes from the operating system's generator, base64url (43
/// characters): nothing a client sees or the clock says predicts it.
pub fn secret() -> String {
    let mut bytes = [0u8; 32];
    // Without the system's randomness no secret may be made at all; on the
    // systems the lab runs on (Linux's getrandom) this does not fail.
    getrandom::fill(&mut bytes).expect("the operating system gives random bytes");
    base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(bytes)
}

#[cfg(test)]
mod tests {
    #[test]
    fn secrets_are_long_url_safe_and_never_repeat() {
        let drawn: std::collections::HashSet<String> = (0..1000).map(|_| super::secret()).collect();
        assert_eq!(drawn.len(), 1000);
        assert!(drawn.iter().all(|s| {
            s.len() == 43
                && s.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
        }));
    }
}
