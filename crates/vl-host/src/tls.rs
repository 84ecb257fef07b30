//! WebSocket over TLS (`wss://`): the Host's certificate and key, from PEM
//! files (`--tls-cert`, `--tls-key`) or made afresh and self-signed
//! (`--tls-self-signed`), with the fingerprint a Guest pins it by. With
//! TLS on, a plain `ws://` handshake fails: the Host speaks only TLS.

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
}

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

    /// A certificate made now for `names` (host names or addresses), signed
    /// by its own key: Guests pin it by its fingerprint.
    pub fn self_signed(names: Vec<String>) -> Result<Tls, TlsError> {
        let made = rcgen::generate_simple_self_signed(names)?;
        let key = PrivateKeyDer::try_from(made.signing_key.serialize_der())
            .map_err(|why| TlsError::Config(rustls::Error::General(why.to_owned())))?;
        Tls::new(vec![made.cert.der().clone()], key, Path::new("self-signed"))
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
