//! The `tls_*` files read into what rustls speaks TLS with: the roots a broker's
//! certificate must chain to and the bridge's own certificate and key. Read and checked
//! before anything runs, so that a file that is missing, holds the wrong thing or does not
//! go with its pair is refused naming its key and path, not found out at the first
//! connection, where it would only be said as a broker that cannot be reached.
//!
//! The cryptography is ring's, named here rather than taken from rustls's process-wide
//! default, which exists only when exactly one provider is built in.

use std::path::Path;
use std::sync::Arc;

use rustls::pki_types::pem::{self, PemObject};
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use rustls::{ClientConfig, RootCertStore};

use super::{invalid, TelemetryError, TlsConfig};

/// The client's TLS: the broker's certificate verified against the certificates in `ca`
/// (else the system's roots), the bridge shown by `client`'s certificate and key if given.
pub(super) fn client_config(
    ca: Option<&Path>,
    client: Option<(&Path, &Path)>,
) -> Result<TlsConfig, TelemetryError> {
    let roots = match ca {
        Some(ca) => shop_roots(ca)?,
        None => system_roots()?,
    };
    let builder =
        ClientConfig::builder_with_provider(Arc::new(rustls::crypto::ring::default_provider()))
            .with_safe_default_protocol_versions()
            .expect("ring speaks TLS 1.2 and 1.3")
            .with_root_certificates(roots);
    let config = match client {
        None => builder.with_no_client_auth(),
        Some((cert, key)) => {
            let chain = certificates(cert, "tls_cert")?;
            let private = private_key(key)?;
            builder.with_client_auth_cert(chain, private).map_err(|e| {
                invalid(
                    "tls_key",
                    format!(
                        "{} cannot be used with the certificate in {} ({e}): give the \
                             key the certificate was made for",
                        key.display(),
                        cert.display()
                    ),
                )
            })?
        }
    };
    Ok(Arc::new(config))
}

/// The shop's CA: every certificate in the file a root, each one that is not refused.
fn shop_roots(path: &Path) -> Result<RootCertStore, TelemetryError> {
    let mut roots = RootCertStore::empty();
    for (n, certificate) in certificates(path, "tls_ca")?.into_iter().enumerate() {
        roots.add(certificate).map_err(|e| {
            invalid(
                "tls_ca",
                format!(
                    "certificate {} in {} is not one a broker can be verified against ({e})",
                    n + 1,
                    path.display()
                ),
            )
        })?;
    }
    Ok(roots)
}

/// The system's root certificates (its CA bundle, or `SSL_CERT_FILE`/`SSL_CERT_DIR` where
/// set); refused, naming `tls_ca`, where there are none: no broker could be verified.
fn system_roots() -> Result<RootCertStore, TelemetryError> {
    let found = rustls_native_certs::load_native_certs();
    let mut roots = RootCertStore::empty();
    roots.add_parsable_certificates(found.certs);
    if roots.is_empty() {
        let why: Vec<String> = found.errors.iter().map(ToString::to_string).collect();
        return Err(invalid(
            "tls_ca",
            format!(
                "none is given, and this system has no root certificates to verify the \
                 broker's with{}: give the shop's CA (or install ca-certificates)",
                if why.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", why.join("; "))
                }
            ),
        ));
    }
    Ok(roots)
}

/// The file at `path` (the value of `key`).
fn read(path: &Path, key: &str) -> Result<Vec<u8>, TelemetryError> {
    std::fs::read(path).map_err(|e| invalid(key, format!("cannot read {} ({e})", path.display())))
}

/// The certificates in the PEM file at `path` (the value of `key`), at least one.
fn certificates(path: &Path, key: &str) -> Result<Vec<CertificateDer<'static>>, TelemetryError> {
    let text = read(path, key)?;
    let certificates = CertificateDer::pem_slice_iter(&text)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| not_pem(path, key, &e))?;
    if certificates.is_empty() {
        return Err(invalid(
            key,
            format!(
                "{} holds no certificate (PEM, `-----BEGIN CERTIFICATE-----`)",
                path.display()
            ),
        ));
    }
    Ok(certificates)
}

/// The private key in the PEM file at `path` (`tls_key`'s value).
fn private_key(path: &Path) -> Result<PrivateKeyDer<'static>, TelemetryError> {
    let text = read(path, "tls_key")?;
    PrivateKeyDer::from_pem_slice(&text).map_err(|e| match e {
        pem::Error::NoItemsFound => invalid(
            "tls_key",
            format!(
                "{} holds no private key (PEM, `-----BEGIN PRIVATE KEY-----`, `RSA PRIVATE \
                 KEY` or `EC PRIVATE KEY`; an encrypted key is not read)",
                path.display()
            ),
        ),
        e => not_pem(path, "tls_key", &e),
    })
}

fn not_pem(path: &Path, key: &str, e: &pem::Error) -> TelemetryError {
    invalid(key, format!("{} is not PEM ({e})", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rcgen::{CertificateParams, CertifiedIssuer, IsCa, KeyPair};

    /// A CA, and a client certificate and key it signs, as PEM.
    fn made() -> (String, String, String) {
        let mut params = CertificateParams::new(Vec::<String>::new()).unwrap();
        params.is_ca = IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
        let ca = CertifiedIssuer::self_signed(params, KeyPair::generate().unwrap()).unwrap();
        let key = KeyPair::generate().unwrap();
        let cert = CertificateParams::new(vec!["lathe3".to_owned()])
            .unwrap()
            .signed_by(&key, &ca)
            .unwrap();
        (ca.pem(), cert.pem(), key.serialize_pem())
    }

    #[test]
    fn the_shops_ca_and_the_bridges_certificate_make_a_client() {
        let dir = tempfile::tempdir().unwrap();
        let (ca, cert, key) = made();
        let at = |name: &str, text: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, text).unwrap();
            path
        };
        let (ca, cert, key) = (at("ca.pem", &ca), at("c.crt", &cert), at("c.key", &key));
        let config = client_config(Some(&ca), Some((&cert, &key))).unwrap();
        assert!(config.client_auth_cert_resolver.has_certs());
        let anonymous = client_config(Some(&ca), None).unwrap();
        assert!(!anonymous.client_auth_cert_resolver.has_certs());
    }

    #[test]
    fn each_wrong_file_is_refused_naming_its_key_and_path() {
        let dir = tempfile::tempdir().unwrap();
        let (ca, cert, key) = made();
        let (_, _, other_key) = made();
        let at = |name: &str, text: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, text).unwrap();
            path
        };
        let (ca, cert, key) = (at("ca.pem", &ca), at("c.crt", &cert), at("c.key", &key));
        let other_key = at("other.key", &other_key);
        let missing = dir.path().join("missing.pem");
        let empty = at("empty.pem", "");
        let garbled = at(
            "garbled.pem",
            "-----BEGIN CERTIFICATE-----\nnot base64!\n-----END CERTIFICATE-----\n",
        );
        let says = |error: TelemetryError, key: &str, path: &Path, what: &str| {
            assert_eq!(error.key, key, "{error}");
            assert!(
                error.problem.contains(&path.display().to_string()) && error.problem.contains(what),
                "{error}"
            );
        };
        for (bad, what) in [
            (&missing, "cannot read"),
            (&empty, "holds no certificate"),
            (&garbled, "is not PEM"),
        ] {
            says(
                client_config(Some(bad), None).unwrap_err(),
                "tls_ca",
                bad,
                what,
            );
        }
        // A key where the certificate belongs holds no certificate, and the other way.
        for ((c, k), named, bad, what) in [
            ((&key, &key), "tls_cert", &key, "no certificate"),
            ((&cert, &cert), "tls_key", &cert, "no private key"),
            ((&cert, &missing), "tls_key", &missing, "cannot read"),
            (
                (&cert, &other_key),
                "tls_key",
                &other_key,
                "cannot be used with the certificate",
            ),
        ] {
            let error = client_config(Some(&ca), Some((c, k))).unwrap_err();
            says(error, named, bad, what);
        }
    }
}
