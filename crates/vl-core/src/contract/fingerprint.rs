//! A TLS certificate's fingerprint, the SHA-256 of its DER: what a Host
//! with a self-signed certificate shows when it starts, and what a Guest
//! pins (`wss://host:port/#pin=…`) to trust that certificate and no other.

use std::fmt;
use std::str::FromStr;

use sha2::{Digest, Sha256};

use crate::SyntaxError;

/// SHA-256 of a certificate's DER.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fingerprint(pub [u8; 32]);

impl Fingerprint {
    pub fn of(der: &[u8]) -> Fingerprint {
        Fingerprint(Sha256::digest(der).into())
    }
}

/// 64 lowercase hex digits.
impl fmt::Display for Fingerprint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

/// 64 hex digits, in either case, colons between bytes allowed (as
/// `openssl x509 -fingerprint -sha256` writes them).
impl FromStr for Fingerprint {
    type Err = SyntaxError;

    fn from_str(text: &str) -> Result<Fingerprint, SyntaxError> {
        let refused = || SyntaxError::Range {
            got: text.to_owned(),
            what: "a SHA-256 fingerprint: 64 hex digits".into(),
        };
        let digits: String = text.chars().filter(|c| *c != ':').collect();
        if digits.len() != 64 || !digits.is_ascii() {
            return Err(refused());
        }
        let mut bytes = [0u8; 32];
        for (i, byte) in bytes.iter_mut().enumerate() {
            *byte = u8::from_str_radix(&digits[2 * i..2 * i + 2], 16).map_err(|_| refused())?;
        }
        Ok(Fingerprint(bytes))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fingerprint_reads_back_as_written_with_or_without_colons() {
        let f = Fingerprint::of(b"a certificate");
        let text = f.to_string();
        assert_eq!(text.len(), 64);
        assert_eq!(text.parse(), Ok(f));
        let colons: Vec<String> = f.0.iter().map(|b| format!("{b:02X}")).collect();
        assert_eq!(colons.join(":").parse(), Ok(f));
        assert!("abc".parse::<Fingerprint>().is_err());
        assert!(text.replace('a', "g").parse::<Fingerprint>().is_err() || !text.contains('a'));
    }
}
