//! WebSocket over TLS (`wss://`): the Host's certificate and key, from PEM
//! files (`--tls-cert`, `--tls-key`) or self-signed (`--tls-self-signed`:
//! made once and kept, so the fingerprint a Guest pins it by lasts from one
//! start of the Host to the next, until it is renewed). With TLS on, a
//! plain `ws://` handshake fails: the Host speaks only TLS.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustls::ServerConfig;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use vl_core::Fingerprint;

/// The Host's side of TLS.
#[derive(Debug, Clone)]
pub struct Tls {
    pub(crate) config: Arc<ServerConfig>,
    /// The certificate's (the chain's first).
    pub fingerprint: Fingerprint,
}

/// Why the Host cannot speak TLS so.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    #[error("cannot read {path}: {why}")]
    Read { path: PathBuf, why: String },
    #[error("{0} holds no certificate")]
    NoCertificate(PathBuf),
    #[error("the certificate and key do not make a TLS server: {0}")]
    Config(#[from] rustls::Error),
    #[error("cannot make a self-signed certificate: {0}")]
    SelfSigned(#[from] rcgen::Error),
    #[error("cannot keep the self-signed certificate in {path}: {why}")]
    Keep { path: PathBuf, why: std::io::Error },
}

/// The kept self-signed certificate's file in its folder: the certificate
/// and its key in one PEM file, so a reader never pairs one Host's
/// certificate with another's key.
const SELF_SIGNED: &str = "self-signed.pem";

impl Tls {
    /// From a PEM certificate chain and its PEM private key.
    pub fn from_files(cert: &Path, key: &Path) -> Result<Tls, TlsError> {
        let read = |path: &Path| {
            let path = path.to_owned();
            move |e: rustls::pki_types::pem::Error| TlsError::Read {
                why: e.to_string(),
                path,
            }
        };
        let chain = CertificateDer::pem_file_iter(cert)
            .map_err(read(cert))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(read(cert))?;
        let key = PrivateKeyDer::from_pem_file(key).map_err(read(key))?;
        Tls::new(chain, key, cert)
    }

    /// The self-signed certificate kept in `dir` (its key readable by this
    /// user alone), made for `names` (host names or addresses) when there is
    /// none yet or `renew` asks for a new one: Guests pin it by its
    /// fingerprint, which stays the same from one start to the next.
    pub fn self_signed_kept(dir: &Path, names: Vec<String>, renew: bool) -> Result<Tls, TlsError> {
        let file = dir.join(SELF_SIGNED);
        if renew || !file.exists() {
            let made = rcgen::generate_simple_self_signed(names)?;
            let pem = format!("{}{}", made.cert.pem(), made.signing_key.serialize_pem());
            keep(dir, &pem).map_err(|why| TlsError::Keep {
                path: file.clone(),
                why,
            })?;
        }
        Tls::from_files(&file, &file)
    }

    fn new(
        chain: Vec<CertificateDer<'static>>,
        key: PrivateKeyDer<'static>,
        from: &Path,
    ) -> Result<Tls, TlsError> {
        let first = chain
            .first()
            .ok_or_else(|| TlsError::NoCertificate(from.to_owned()))?;
        let fingerprint = Fingerprint::of(first);
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let config = ServerConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()?
            .with_no_client_auth()
            .with_single_cert(chain, key)?;
        Ok(Tls {
            config: Arc::new(config),
            fingerprint,
        })
    }
}

/// Writes `pem` as the kept certificate in `dir`, whole or not at all (a
/// file beside it renamed over it), readable by this user alone.
fn keep(dir: &Path, pem: &str) -> std::io::Result<()> {
    use std::io::Write;
    std::fs::create_dir_all(dir)?;
    let fresh = dir.join(format!("{SELF_SIGNED}.{}", std::process::id()));
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut out = options.open(&fresh)?;
    out.write_all(pem.as_bytes())?;
    out.sync_all()?;
    std::fs::rename(&fresh, dir.join(SELF_SIGNED))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kept_certificate_is_the_same_until_renewed_and_its_key_is_private() {
        let dir = std::env::temp_dir().join(format!("vl-tls-kept-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let names = || vec!["localhost".to_owned()];
        let first = Tls::self_signed_kept(&dir, names(), false).unwrap();
        let again = Tls::self_signed_kept(&dir, names(), false).unwrap();
        assert_eq!(first.fingerprint, again.fingerprint);
        let renewed = Tls::self_signed_kept(&dir, names(), true).unwrap();
        assert_ne!(first.fingerprint, renewed.fingerprint);
        let after = Tls::self_signed_kept(&dir, names(), false).unwrap();
        assert_eq!(renewed.fingerprint, after.fingerprint);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(dir.join(SELF_SIGNED))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o077, 0, "{mode:o}");
        }
        let _ = std::fs::remove_dir_all(dir);
    }
}
