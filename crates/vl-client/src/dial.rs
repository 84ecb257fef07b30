//! Reaching a Host: `ws://` over TCP, or `wss://` over TLS, trusting the
//! public certificate authorities or, with `#pin=` on the URL, exactly the
//! certificate of that fingerprint (a Host's self-signed one, which it
//! shows when it starts).

use std::sync::Arc;

use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::{CryptoProvider, WebPkiSupportedAlgorithms};
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use rustls::{ClientConfig, DigitallySignedStruct, SignatureScheme};
use tokio::net::TcpStream;
use vl_core::Fingerprint;
use vl_core::Io;

/// Where a Host is and how to reach it.
#[derive(Debug, Clone)]
pub(crate) struct Target {
    /// The WebSocket URL, without the pin.
    pub(crate) url: String,
    host: String,
    port: u16,
    /// For `wss://`: the certificate's fingerprint to pin, if given.
    tls: Option<Option<Fingerprint>>,
}

impl Target {
    /// `url` as ws://host[:port][/…] or wss://host[:port][/…][#pin=HEX];
    /// why not, in words.
    pub(crate) fn of(url: &str) -> Result<Target, String> {
        // "host:7400" would parse as a URL of scheme "host".
        let Some((_, rest)) = url.split_once("://") else {
            return Err(format!("it has no scheme: try ws://{url}"));
        };
        let mut parsed = url::Url::parse(url).map_err(|e| match e {
            url::ParseError::EmptyHost => "it names no host".to_owned(),
            url::ParseError::InvalidPort => "its port is not a port number".to_owned(),
            e => e.to_string(),
        })?;
        let tls = match parsed.scheme() {
            "ws" => false,
            "wss" => true,
            other => {
                return Err(format!(
                    "a Host speaks WebSocket, not {other}://: try ws://{rest}"
                ));
            }
        };
        let pin = match parsed.fragment() {
            Some(fragment) => {
                let pin = fragment.strip_prefix("pin=").ok_or_else(|| {
                    format!(
                        "'#{fragment}': the only fragment a Host's address has is #pin=FINGERPRINT"
                    )
                })?;
                let pin: Fingerprint = pin.parse().map_err(|e| format!("#pin: {e}"))?;
                if !tls {
                    return Err("a pin is for wss:// (WebSocket over TLS)".into());
                }
                Some(pin)
            }
            None => None,
        };
        // An IPv6 address unbracketed, as a socket address takes it.
        let host = (parsed.host_str())
            .map(|h| h.trim_start_matches('[').trim_end_matches(']').to_owned())
            .ok_or("it names no host")?;
        let port = parsed.port_or_known_default().ok_or("it names no port")?;
        parsed.set_fragment(None);
        Ok(Target {
            url: parsed.into(),
            host,
            port,
            tls: tls.then_some(pin),
        })
    }

    /// `host:port`, as an HTTP request's `Host` names it.
    pub(crate) fn authority(&self) -> String {
        match self.host.contains(':') {
            true => format!("[{}]:{}", self.host, self.port),
            false => format!("{}:{}", self.host, self.port),
        }
    }

    /// A byte stream to the Host, TLS already shaken hands when asked for.
    pub(crate) async fn dial(&self) -> std::io::Result<Box<dyn Io>> {
        let tcp = TcpStream::connect((self.host.as_str(), self.port)).await?;
        let _ = tcp.set_nodelay(true);
        let Some(pin) = self.tls else {
            return Ok(Box::new(tcp));
        };
        let name = ServerName::try_from(self.host.clone())
            .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
        let connector = tokio_rustls::TlsConnector::from(Arc::new(client_config(pin)));
        Ok(Box::new(connector.connect(name, tcp).await?))
    }
}

fn provider() -> Arc<CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

/// Trusts `pin`'s certificate only, or else the public authorities.
fn client_config(pin: Option<Fingerprint>) -> ClientConfig {
    let builder = ClientConfig::builder_with_provider(provider())
        .with_safe_default_protocol_versions()
        .expect("ring supports the safe default versions");
    match pin {
        Some(pin) => builder
            .dangerous()
            .with_custom_certificate_verifier(Arc::new(Pinned {
                pin,
                algorithms: provider().signature_verification_algorithms,
            }))
            .with_no_client_auth(),
        None => {
            let roots = rustls::RootCertStore {
                roots: webpki_roots::TLS_SERVER_ROOTS.to_vec(),
            };
            builder.with_root_certificates(roots).with_no_client_auth()
        }
    }
}

/// Trusts exactly the certificate with this fingerprint, whoever signed
/// it, and checks the handshake is signed by its key.
#[derive(Debug)]
struct Pinned {
    pin: Fingerprint,
    algorithms: WebPkiSupportedAlgorithms,
}

impl ServerCertVerifier for Pinned {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        let got = Fingerprint::of(end_entity);
        if got == self.pin {
            Ok(ServerCertVerified::assertion())
        } else {
            Err(rustls::Error::General(format!(
                "the Host's certificate is {got}, not the pinned {}",
                self.pin
            )))
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls12_signature(message, cert, dss, &self.algorithms)
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls13_signature(message, cert, dss, &self.algorithms)
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.algorithms.supported_schemes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_say_where_and_how() {
        let plain = Target::of("ws://127.0.0.1:7400").unwrap();
        assert_eq!(
            (plain.host.as_str(), plain.port, plain.tls),
            ("127.0.0.1", 7400, None)
        );
        let pin = Fingerprint::of(b"cert");
        let pinned = Target::of(&format!("wss://lab.example.org/#pin={pin}")).unwrap();
        assert_eq!(pinned.url, "wss://lab.example.org/");
        assert_eq!((pinned.port, pinned.tls), (443, Some(Some(pin))));
        let v6 = Target::of("ws://[::1]:9000").unwrap();
        assert_eq!((v6.host.as_str(), v6.port), ("::1", 9000));
        let v6 = Target::of("wss://[::1]/").unwrap();
        assert_eq!((v6.host.as_str(), v6.port), ("::1", 443));
        for (bad, why) in [
            ("http://x:1", "not http://"),
            ("x:1", "no scheme"),
            ("ws://", "names no host"),
            ("ws://x:1/#pin=00", "SHA-256"),
            ("ws://x:1/#frag", "only fragment"),
            ("wss://x:port", "not a port"),
        ] {
            let e = Target::of(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }
}
