//! Where and how a client reaches a learner: the address, plaintext or TLS (with the files that
//! configure it), and the rule that a token never travels in clear to anything but loopback
//! unless the user says so (`--insecure-plaintext`).

use std::net::IpAddr;
use std::path::{Path, PathBuf};

use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tonic::transport::{Certificate, ClientTlsConfig, Identity};

/// The TLS files of a client: the CA that signed the learner's certificate and, for mutual TLS,
/// this client's own certificate and key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    /// PEM certificate(s) of the CA the learner's certificate must chain to (`--tls-ca`).
    pub ca: PathBuf,
    /// PEM certificate and private key this client presents (`--tls-cert`, `--tls-key`).
    pub identity: Option<(PathBuf, PathBuf)>,
}

/// A learner's address with the way to speak to it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Target {
    /// `http://HOST:PORT` or `https://HOST:PORT`.
    pub url: String,
    /// The host as written (a name or an IP, without brackets): the name the learner's
    /// certificate must be valid for.
    pub host: String,
    pub port: u16,
    /// Set exactly when the URL is `https://`.
    pub tls: Option<TlsFiles>,
    /// `--insecure-plaintext`: send a token over plaintext to a non-loopback address anyway.
    pub insecure_plaintext: bool,
}

/// Why an address, a TLS file or the token rule stops a client before it connects.
#[derive(Debug, thiserror::Error)]
pub enum TargetError {
    #[error("`{addr}` is not a valid address: {why} (expected HOST:PORT, http://HOST:PORT or https://HOST:PORT)")]
    BadAddress { addr: String, why: String },
    #[error("`{addr}` asks for TLS (https://) but no --tls-ca FILE names the CA that signed the learner's certificate")]
    HttpsWithoutCa { addr: String },
    #[error("`{addr}` asks for plaintext (http://) but --tls-ca is given: write https://HOST:PORT (or HOST:PORT) to use TLS")]
    HttpWithCa { addr: String },
    #[error("reading TLS file {} ({what})", path.display())]
    ReadFile {
        path: PathBuf,
        what: &'static str,
        #[source]
        source: std::io::Error,
    },
    #[error("TLS file {} ({what}) holds no PEM {expected}", path.display())]
    NotPem { path: PathBuf, what: &'static str, expected: &'static str },
    #[error(
        "refusing to send the auth token in clear to {host}, which is not a loopback address: connect with TLS \
         (https://{host}:{port} and --tls-ca FILE), or pass --insecure-plaintext if this network is trusted"
    )]
    TokenInClear { host: String, port: u16 },
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.url)
    }
}

impl Target {
    /// Reads `addr` (`HOST:PORT`, `http://HOST:PORT` or `https://HOST:PORT`). TLS files make a
    /// bare `HOST:PORT` TLS; `https://` needs them and `http://` refuses them, so that a
    /// contradiction is an error rather than a guess.
    pub fn new(addr: &str, tls: Option<TlsFiles>, insecure_plaintext: bool) -> Result<Self, TargetError> {
        let (scheme, rest) = match addr.split_once("://") {
            Some((s @ ("http" | "https"), rest)) => (Some(s), rest),
            Some((other, _)) => return Err(bad(addr, &format!("unknown scheme `{other}://`"))),
            None => (None, addr),
        };
        let use_tls = match (scheme, &tls) {
            (Some("https"), None) => return Err(TargetError::HttpsWithoutCa { addr: addr.to_owned() }),
            (Some("http"), Some(_)) => return Err(TargetError::HttpWithCa { addr: addr.to_owned() }),
            (_, t) => t.is_some(),
        };
        let authority = rest.trim_end_matches('/');
        let (host, port) = authority.rsplit_once(':').ok_or_else(|| bad(addr, "no port"))?;
        let port: u16 = port.parse().map_err(|_| bad(addr, &format!("port `{port}` is not a number 0..=65535")))?;
        let host = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')).unwrap_or(host);
        if host.is_empty() || host.contains(['/', '@', ' ']) {
            return Err(bad(addr, &format!("host `{host}`")));
        }
        let shown = if host.contains(':') { format!("[{host}]") } else { host.to_owned() };
        let url = format!("{}://{shown}:{port}", if use_tls { "https" } else { "http" });
        Ok(Self { url, host: host.to_owned(), port, tls, insecure_plaintext })
    }

    /// A plaintext or TLS target from an address alone (no TLS files, no override).
    pub fn plain(addr: &str) -> Result<Self, TargetError> {
        Self::new(addr, None, false)
    }

    /// Refuses, before any connection, to send a token in clear to a host that is not loopback
    /// (every address it resolves to must be), unless TLS is on or `--insecure-plaintext` given.
    pub async fn check_token_safety(&self) -> Result<(), TargetError> {
        if self.tls.is_some() || self.insecure_plaintext || self.is_loopback().await {
            return Ok(());
        }
        Err(TargetError::TokenInClear { host: self.host.clone(), port: self.port })
    }

    /// Whether the host is loopback: an IP that is, `localhost`, or a name all of whose
    /// addresses are (one that does not resolve is not).
    async fn is_loopback(&self) -> bool {
        if let Ok(ip) = self.host.parse::<IpAddr>() {
            return ip.is_loopback();
        }
        if self.host.eq_ignore_ascii_case("localhost") {
            return true;
        }
        match tokio::net::lookup_host((self.host.as_str(), self.port)).await {
            Ok(addrs) => {
                let addrs: Vec<_> = addrs.collect();
                !addrs.is_empty() && addrs.iter().all(|a| a.ip().is_loopback())
            }
            Err(_) => false,
        }
    }

    /// tonic's client TLS configuration from the files (read now, so that a rotated file is
    /// used by the next connection), or `None` for plaintext.
    pub fn client_tls_config(&self) -> Result<Option<ClientTlsConfig>, TargetError> {
        let Some(files) = &self.tls else { return Ok(None) };
        let ca = read_certificates(&files.ca, "--tls-ca")?;
        let mut cfg = ClientTlsConfig::new().ca_certificate(Certificate::from_pem(ca)).domain_name(self.host.clone());
        if let Some((cert, key)) = &files.identity {
            let cert = read_certificates(cert, "--tls-cert")?;
            let key = read_private_key(key, "--tls-key")?;
            cfg = cfg.identity(Identity::from_pem(cert, key));
        }
        Ok(Some(cfg))
    }
}

fn bad(addr: &str, why: &str) -> TargetError {
    TargetError::BadAddress { addr: addr.to_owned(), why: why.to_owned() }
}

fn read(path: &Path, what: &'static str) -> Result<Vec<u8>, TargetError> {
    std::fs::read(path).map_err(|source| TargetError::ReadFile { path: path.to_owned(), what, source })
}

/// A PEM file's bytes, checked to hold at least one certificate.
pub fn read_certificates(path: &Path, what: &'static str) -> Result<Vec<u8>, TargetError> {
    let bytes = read(path, what)?;
    if CertificateDer::pem_slice_iter(&bytes).next().is_none_or(|c| c.is_err()) {
        return Err(TargetError::NotPem { path: path.to_owned(), what, expected: "certificate (-----BEGIN CERTIFICATE-----)" });
    }
    Ok(bytes)
}

/// A PEM file's bytes, checked to hold a private key.
pub fn read_private_key(path: &Path, what: &'static str) -> Result<Vec<u8>, TargetError> {
    let bytes = read(path, what)?;
    if PrivateKeyDer::from_pem_slice(&bytes).is_err() {
        return Err(TargetError::NotPem { path: path.to_owned(), what, expected: "private key (-----BEGIN PRIVATE KEY-----)" });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files() -> Option<TlsFiles> {
        Some(TlsFiles { ca: "ca.pem".into(), identity: None })
    }

    #[test]
    fn addresses_and_schemes() {
        assert_eq!(Target::plain("127.0.0.1:5").unwrap().url, "http://127.0.0.1:5");
        assert_eq!(Target::plain("http://h:5/").unwrap().url, "http://h:5");
        let t = Target::new("[::1]:7", files(), false).unwrap();
        assert_eq!((t.url.as_str(), t.host.as_str(), t.port), ("https://[::1]:7", "::1", 7));
        assert_eq!(Target::new("https://learner:50051", files(), false).unwrap().host, "learner");
        assert!(matches!(Target::plain("https://h:1"), Err(TargetError::HttpsWithoutCa { .. })));
        assert!(matches!(Target::new("http://h:1", files(), false), Err(TargetError::HttpWithCa { .. })));
        for wrong in ["h", "h:x", "ftp://h:1", ":5", "h:70000"] {
            assert!(matches!(Target::plain(wrong), Err(TargetError::BadAddress { .. })), "{wrong}");
        }
    }

    #[tokio::test]
    async fn a_token_goes_in_clear_only_to_loopback_or_with_the_override() {
        for ok in ["127.0.0.1:1", "[::1]:1", "localhost:1"] {
            Target::plain(ok).unwrap().check_token_safety().await.unwrap();
        }
        let e = Target::plain("10.1.2.3:50051").unwrap().check_token_safety().await.unwrap_err();
        assert!(e.to_string().contains("--insecure-plaintext"), "{e}");
        assert!(e.to_string().contains("10.1.2.3"), "{e}");
        Target::new("10.1.2.3:50051", None, true).unwrap().check_token_safety().await.unwrap();
        Target::new("10.1.2.3:50051", files(), false).unwrap().check_token_safety().await.unwrap();
        // A name that does not resolve is not loopback.
        assert!(Target::plain("no-such-host.invalid:1").unwrap().check_token_safety().await.is_err());
    }
}
