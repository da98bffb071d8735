//! `learner certs`: certificates for users who have none — a CA, a server certificate for the
//! learner's host names and IPs, and one client certificate for mutual TLS, made with `rcgen`
//! (ECDSA P-256). Keys are written with mode 0600, every file atomically (a learner watching
//! them never reads half of one). A CA already in the directory is kept, so running the command
//! again renews the server and client certificates and clients go on trusting the same `ca.pem`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair, KeyUsagePurpose,
};
use time::{Duration, OffsetDateTime};

/// File names `learner certs` writes.
pub const CA_CERT: &str = "ca.pem";
pub const CA_KEY: &str = "ca-key.pem";
pub const SERVER_CERT: &str = "server.pem";
pub const SERVER_KEY: &str = "server-key.pem";
pub const CLIENT_CERT: &str = "client.pem";
pub const CLIENT_KEY: &str = "client-key.pem";

/// The CA's common name: the CA is rebuilt from its key and this name when kept.
const CA_NAME: &str = "hybrid-drive learner CA";

/// From when to when a certificate is valid.
#[derive(Debug, Clone, Copy)]
pub struct Validity {
    pub not_before: OffsetDateTime,
    pub not_after: OffsetDateTime,
}

impl Validity {
    /// From an hour ago (clocks differ a little) for `days` days.
    #[must_use]
    pub fn days_from_now(days: i64) -> Self {
        let now = OffsetDateTime::now_utc();
        Self { not_before: now - Duration::hours(1), not_after: now + Duration::days(days) }
    }
}

/// A certificate and its private key, PEM.
#[derive(Debug, Clone)]
pub struct Pem {
    pub cert: String,
    pub key: String,
}

/// A certificate authority that signs server and client certificates.
#[derive(Debug)]
pub struct Ca {
    issuer: Issuer<'static, KeyPair>,
    pub pem: Pem,
}

fn ca_params(validity: Validity) -> CertificateParams {
    let mut p = CertificateParams::default();
    p.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    p.distinguished_name = DistinguishedName::new();
    p.distinguished_name.push(DnType::CommonName, CA_NAME);
    p.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign, KeyUsagePurpose::DigitalSignature];
    p.not_before = validity.not_before;
    p.not_after = validity.not_after;
    p
}

impl Ca {
    /// A new CA.
    pub fn new(validity: Validity) -> Result<Self> {
        let key = KeyPair::generate()?;
        let params = ca_params(validity);
        let cert = params.self_signed(&key)?.pem();
        let pem = Pem { cert, key: key.serialize_pem() };
        Ok(Self { issuer: Issuer::new(params, key), pem })
    }

    /// The CA `learner certs` wrote earlier (its certificate and key PEM).
    pub fn from_pem(cert: &str, key: &str) -> Result<Self> {
        let key_pair = KeyPair::from_pem(key).context("the CA key is not a PEM private key")?;
        // Only the name, key usages and key sign; the validity shown is the stored certificate's.
        let params = ca_params(Validity::days_from_now(1));
        Ok(Self { issuer: Issuer::new(params, key_pair), pem: Pem { cert: cert.to_owned(), key: key.to_owned() } })
    }

    /// A server certificate valid for `hosts` (names or IP addresses).
    pub fn server(&self, hosts: &[String], validity: Validity) -> Result<Pem> {
        let mut p = CertificateParams::new(hosts.to_vec())?;
        p.distinguished_name.push(DnType::CommonName, hosts.first().map_or("learner", String::as_str));
        p.extended_key_usages = vec![ExtendedKeyUsagePurpose::ServerAuth];
        p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        self.sign(p, validity)
    }

    /// A client certificate named `name`.
    pub fn client(&self, name: &str, validity: Validity) -> Result<Pem> {
        let mut p = CertificateParams::default();
        p.distinguished_name.push(DnType::CommonName, name);
        p.extended_key_usages = vec![ExtendedKeyUsagePurpose::ClientAuth];
        p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        self.sign(p, validity)
    }

    fn sign(&self, mut p: CertificateParams, validity: Validity) -> Result<Pem> {
        p.not_before = validity.not_before;
        p.not_after = validity.not_after;
        let key = KeyPair::generate()?;
        let cert = p.signed_by(&key, &self.issuer)?.pem();
        Ok(Pem { cert, key: key.serialize_pem() })
    }
}

/// Writes a CA (kept if `dir` has one), a server certificate for `hosts` and a client
/// certificate into `dir`, valid for `days`; returns the files written.
pub fn write_set(dir: &Path, hosts: &[String], days: i64) -> Result<Vec<PathBuf>> {
    if hosts.is_empty() || hosts.iter().any(|h| h.trim().is_empty() || h.contains(char::is_whitespace)) {
        bail!("--hosts: give host names or IP addresses separated by commas, e.g. localhost,127.0.0.1,learner");
    }
    if !(1..=3650).contains(&days) {
        bail!("--days {days}: must be 1..=3650");
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let (ca_cert, ca_key) = (dir.join(CA_CERT), dir.join(CA_KEY));
    let mut written = Vec::new();
    let ca = if ca_cert.exists() && ca_key.exists() {
        let read = |p: &Path| std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()));
        Ca::from_pem(&read(&ca_cert)?, &read(&ca_key)?).with_context(|| format!("using the CA in {}", dir.display()))?
    } else {
        let ca = Ca::new(Validity::days_from_now(3650))?;
        write_file(&ca_cert, &ca.pem.cert, 0o644)?;
        write_file(&ca_key, &ca.pem.key, 0o600)?;
        written.extend([ca_cert.clone(), ca_key]);
        ca
    };
    let validity = Validity::days_from_now(days);
    let server = ca.server(hosts, validity)?;
    check_chain(&ca.pem.cert, &server.cert, &hosts[0]).with_context(|| {
        format!("the server certificate does not verify against {}: was that CA made by `learner certs`?", ca_cert.display())
    })?;
    let client = ca.client("hybrid-drive-actor", validity)?;
    for (name, pem, mode) in [
        (SERVER_CERT, &server.cert, 0o644),
        (SERVER_KEY, &server.key, 0o600),
        (CLIENT_CERT, &client.cert, 0o644),
        (CLIENT_KEY, &client.key, 0o600),
    ] {
        let p = dir.join(name);
        write_file(&p, pem, mode)?;
        written.push(p);
    }
    Ok(written)
}

/// Verifies `cert` against the CA `ca` for `host` now, as a client would.
fn check_chain(ca: &str, cert: &str, host: &str) -> Result<()> {
    use rustls::pki_types::pem::PemObject;
    use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
    let mut roots = rustls::RootCertStore::empty();
    roots.add(CertificateDer::from_pem_slice(ca.as_bytes())?)?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let verifier = rustls::client::WebPkiServerVerifier::builder_with_provider(Arc::new(roots), provider).build()?;
    let end = CertificateDer::from_pem_slice(cert.as_bytes())?;
    let name = ServerName::try_from(host.to_owned())?;
    use rustls::client::danger::ServerCertVerifier;
    verifier.verify_server_cert(&end, &[], &name, &[], UnixTime::now())?;
    Ok(())
}

/// Writes `text` to `path` with `mode`, atomically.
fn write_file(path: &Path, text: &str, mode: u32) -> Result<()> {
    Ok(agent::atomic_write::write_atomic(path, text.as_bytes(), Some(mode))?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn writes_a_set_with_private_keys_0600_and_keeps_the_ca() {
        let dir = tempfile::tempdir().unwrap();
        let hosts = vec!["localhost".to_owned(), "127.0.0.1".to_owned()];
        let first = write_set(dir.path(), &hosts, 30).unwrap();
        assert_eq!(first.len(), 6);
        for (name, mode) in [(CA_KEY, 0o600), (SERVER_KEY, 0o600), (CLIENT_KEY, 0o600), (CA_CERT, 0o644), (SERVER_CERT, 0o644)] {
            let m = std::fs::metadata(dir.path().join(name)).unwrap().permissions().mode() & 0o777;
            assert_eq!(m, mode, "{name}");
        }
        let ca = std::fs::read_to_string(dir.path().join(CA_CERT)).unwrap();
        let server = std::fs::read_to_string(dir.path().join(SERVER_CERT)).unwrap();
        check_chain(&ca, &server, "127.0.0.1").unwrap();
        assert!(check_chain(&ca, &server, "elsewhere.example").is_err());
        // Again: the CA stays, the server certificate is new and still chains to it.
        let second = write_set(dir.path(), &hosts, 30).unwrap();
        assert_eq!(second.len(), 4);
        assert_eq!(std::fs::read_to_string(dir.path().join(CA_CERT)).unwrap(), ca);
        let renewed = std::fs::read_to_string(dir.path().join(SERVER_CERT)).unwrap();
        assert_ne!(renewed, server);
        check_chain(&ca, &renewed, "localhost").unwrap();
        assert!(write_set(dir.path(), &[], 30).is_err());
    }
}
