//! The learner's TLS: the server's certificate, key and (for mutual TLS) the CA its clients'
//! certificates must chain to, read into rustls configurations that are swapped whole when the
//! files change ([`ServerTls::reload`]); each new connection takes the configuration current when
//! it arrives, open ones keep theirs. tonic's own `ServerTlsConfig` is fixed once the server is
//! built, so the learner accepts TLS itself (`accept.rs`) and hands tonic finished streams;
//! `watch.rs` reloads on SIGHUP and when a file changes.

mod accept;
mod watch;

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, RwLock};
use std::time::SystemTime;

use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use rustls::server::WebPkiClientVerifier;
use rustls::{RootCertStore, ServerConfig};

pub use accept::{TlsListener, accept_tls};
pub use watch::{RELOAD_POLL, watch_and_reload};

/// The files of the server's TLS (`--tls-cert`, `--tls-key`, `--tls-client-ca`; the same keys
/// under `[service]`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServerTlsFiles {
    pub cert: PathBuf,
    pub key: PathBuf,
    /// Turns on mutual TLS: clients must present a certificate signed by this CA.
    pub client_ca: Option<PathBuf>,
}

/// Why TLS files could not be used.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    #[error("reading {what} {}", path.display())]
    Read {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{what} {} holds no PEM {expected}", path.display())]
    NotPem { what: &'static str, path: PathBuf, expected: &'static str },
    #[error("{what} {}: {source}", path.display())]
    Rustls {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: rustls::Error,
    },
    #[error("--tls-client-ca {}: {message}", path.display())]
    ClientCa { path: PathBuf, message: String },
}

/// Which protocol a listener speaks inside TLS (its ALPN).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Alpn {
    /// gRPC: HTTP/2 only.
    Grpc,
    /// The metrics endpoint: HTTP/1.1.
    Http1,
}

/// The server's TLS, reloadable.
#[derive(Debug)]
pub struct ServerTls {
    pub files: ServerTlsFiles,
    current: RwLock<(Arc<ServerConfig>, Arc<ServerConfig>)>,
    stamp: Mutex<Vec<Option<(SystemTime, u64)>>>,
}

impl ServerTls {
    /// Reads the files (an error names the file and what is wrong with it).
    pub fn load(files: ServerTlsFiles) -> Result<Arc<Self>, TlsError> {
        let stamp = stamp(&files);
        let configs = configs(&files)?;
        Ok(Arc::new(Self { files, current: RwLock::new(configs), stamp: Mutex::new(stamp) }))
    }

    /// The configuration a connection arriving now gets.
    #[must_use]
    pub fn current(&self, alpn: Alpn) -> Arc<ServerConfig> {
        let c = self.current.read().expect("tls config lock");
        match alpn {
            Alpn::Grpc => c.0.clone(),
            Alpn::Http1 => c.1.clone(),
        }
    }

    /// Whether mutual TLS is on.
    #[must_use]
    pub fn mutual(&self) -> bool {
        self.files.client_ca.is_some()
    }

    /// Reads the files again and, if they make a valid configuration, serves it to new
    /// connections; otherwise keeps the old one and says why (once per change of the files).
    pub fn reload(&self) -> Result<(), TlsError> {
        *self.stamp.lock().expect("tls stamp lock") = stamp(&self.files);
        let configs = configs(&self.files)?;
        *self.current.write().expect("tls config lock") = configs;
        Ok(())
    }

    /// Whether a file's modification time or length differs from the last load.
    #[must_use]
    pub fn changed_on_disk(&self) -> bool {
        *self.stamp.lock().expect("tls stamp lock") != stamp(&self.files)
    }
}

fn paths(files: &ServerTlsFiles) -> Vec<&Path> {
    let mut p = vec![files.cert.as_path(), files.key.as_path()];
    p.extend(files.client_ca.as_deref());
    p
}

/// Modification time and length of each file (through symbolic links: a Kubernetes Secret
/// volume swaps a link).
fn stamp(files: &ServerTlsFiles) -> Vec<Option<(SystemTime, u64)>> {
    paths(files).iter().map(|p| std::fs::metadata(p).ok().and_then(|m| Some((m.modified().ok()?, m.len())))).collect()
}

fn read(what: &'static str, path: &Path) -> Result<Vec<u8>, TlsError> {
    std::fs::read(path).map_err(|source| TlsError::Read { what, path: path.to_owned(), source })
}

/// The certificates of a PEM file (at least one).
pub fn read_certs(what: &'static str, path: &Path) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let bytes = read(what, path)?;
    let certs: Vec<_> = CertificateDer::pem_slice_iter(&bytes).filter_map(Result::ok).collect();
    if certs.is_empty() {
        return Err(TlsError::NotPem { what, path: path.to_owned(), expected: "certificate (-----BEGIN CERTIFICATE-----)" });
    }
    Ok(certs)
}

fn configs(files: &ServerTlsFiles) -> Result<(Arc<ServerConfig>, Arc<ServerConfig>), TlsError> {
    let one = |alpn: &[u8]| -> Result<Arc<ServerConfig>, TlsError> {
        let mut cfg = config(files)?;
        cfg.alpn_protocols = vec![alpn.to_vec()];
        Ok(Arc::new(cfg))
    };
    Ok((one(b"h2")?, one(b"http/1.1")?))
}

fn config(files: &ServerTlsFiles) -> Result<ServerConfig, TlsError> {
    let certs = read_certs("--tls-cert", &files.cert)?;
    let key_bytes = read("--tls-key", &files.key)?;
    let key = PrivateKeyDer::from_pem_slice(&key_bytes).map_err(|_| TlsError::NotPem {
        what: "--tls-key",
        path: files.key.clone(),
        expected: "private key (-----BEGIN PRIVATE KEY-----)",
    })?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = ServerConfig::builder_with_provider(provider.clone())
        .with_safe_default_protocol_versions()
        .map_err(|source| TlsError::Rustls { what: "--tls-cert", path: files.cert.clone(), source })?;
    let builder = match &files.client_ca {
        None => builder.with_no_client_auth(),
        Some(ca) => {
            let mut roots = RootCertStore::empty();
            for c in read_certs("--tls-client-ca", ca)? {
                roots.add(c).map_err(|source| TlsError::Rustls { what: "--tls-client-ca", path: ca.clone(), source })?;
            }
            let verifier = WebPkiClientVerifier::builder_with_provider(Arc::new(roots), provider)
                .build()
                .map_err(|e| TlsError::ClientCa { path: ca.clone(), message: e.to_string() })?;
            builder.with_client_cert_verifier(verifier)
        }
    };
    // A key that does not match the certificate is refused here, not at the first handshake.
    builder.with_single_cert(certs, key).map_err(|source| TlsError::Rustls {
        what: "--tls-key (with --tls-cert)",
        path: files.key.clone(),
        source,
    })
}
