//! Which `wss://` servers a native client trusts, and what it says when it
//! does not.
//!
//! `--ca-cert FILE` names the authority that signed the server's
//! certificate. The usual self-signed certificate (`openssl req -x509`) is
//! marked as an authority, and a chain check refuses an authority used as
//! the server's own certificate (`CaUsedAsEndEntity`), though curl takes
//! it: so a certificate in the file that *is* the server's certificate,
//! byte for byte, is pinned and accepted (its names must still include the
//! server's, where it has names). A certificate that is not trusted fails
//! the connection at once with what to do, and is never retried: a retry
//! cannot change it.

use std::sync::Arc;

use rustls::client::WebPkiServerVerifier;
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use rustls::{DigitallySignedStruct, SignatureScheme};

/// A TLS client configuration that trusts the certificates in `ca_cert`
/// (PEM): as authorities, and each as a pinned server certificate.
pub fn client_config(ca_cert: &std::path::Path) -> std::io::Result<Arc<rustls::ClientConfig>> {
    use rustls::pki_types::pem::PemObject;
    let bad = |e: String| std::io::Error::other(format!("{}: {e}", ca_cert.display()));
    let mut roots = rustls::RootCertStore::empty();
    let mut pinned = Vec::new();
    for cert in CertificateDer::pem_file_iter(ca_cert).map_err(|e| bad(e.to_string()))? {
        let cert = cert.map_err(|e| bad(e.to_string()))?;
        roots.add(cert.clone()).map_err(|e| bad(e.to_string()))?;
        pinned.push(cert);
    }
    if pinned.is_empty() {
        return Err(bad("no certificate in it".into()));
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let chain = WebPkiServerVerifier::builder_with_provider(Arc::new(roots), provider.clone())
        .build()
        .map_err(|e| bad(e.to_string()))?;
    let verifier = Pinning { chain, pinned };
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| bad(e.to_string()))?
        .dangerous()
        .with_custom_certificate_verifier(Arc::new(verifier))
        .with_no_client_auth();
    Ok(Arc::new(config))
}

/// The chain check, then the pins.
#[derive(Debug)]
struct Pinning {
    chain: Arc<WebPkiServerVerifier>,
    pinned: Vec<CertificateDer<'static>>,
}

impl ServerCertVerifier for Pinning {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        intermediates: &[CertificateDer<'_>],
        server_name: &ServerName<'_>,
        ocsp_response: &[u8],
        now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        let refused = match self.chain.verify_server_cert(
            end_entity,
            intermediates,
            server_name,
            ocsp_response,
            now,
        ) {
            Ok(verified) => return Ok(verified),
            Err(e) => e,
        };
        if !self
            .pinned
            .iter()
            .any(|p| p.as_ref() == end_entity.as_ref())
        {
            return Err(refused);
        }
        // The very certificate the user gave: trusted as it is, for the
        // names it lists (any name, if it lists none).
        let cert = webpki::EndEntityCert::try_from(end_entity).map_err(|e| {
            rustls::Error::InvalidCertificate(rustls::CertificateError::Other(rustls::OtherError(
                Arc::new(e),
            )))
        })?;
        let names = cert.valid_dns_names().count();
        match cert.verify_is_valid_for_subject_name(server_name) {
            Ok(()) => Ok(ServerCertVerified::assertion()),
            Err(_) if names == 0 => Ok(ServerCertVerified::assertion()),
            Err(_) => Err(rustls::Error::InvalidCertificate(
                rustls::CertificateError::NotValidForName,
            )),
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        self.chain.verify_tls12_signature(message, cert, dss)
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        self.chain.verify_tls13_signature(message, cert, dss)
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.chain.supported_verify_schemes()
    }
}

/// Why a connection failed, when it failed on the server's certificate:
/// what was wrong and what to do; `None` for any other failure.
pub fn untrusted(error: &tokio_tungstenite::tungstenite::Error) -> Option<String> {
    use tokio_tungstenite::tungstenite::Error;
    let io = match error {
        Error::Io(io) => io,
        _ => return None,
    };
    let rustls::Error::InvalidCertificate(why) = io.get_ref()?.downcast_ref::<rustls::Error>()?
    else {
        return None;
    };
    Some(format!(
        "the server's certificate is not trusted ({why:?}): pass --ca-cert FILE with the \
         certificate of the authority that signed it, or with the server's own certificate \
         (then pinned); `farfield-server cert --name HOST --out DIR` makes a certificate and \
         key that browsers and this client accept"
    ))
}
