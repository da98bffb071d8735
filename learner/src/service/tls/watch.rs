//! Certificate rotation without a restart: the TLS files are read again on SIGHUP and whenever
//! their modification time or length changes (checked every [`RELOAD_POLL`]; a Kubernetes
//! Secret volume changes files without signalling anyone). A reload that fails keeps the
//! previous configuration and says why.

use std::sync::Arc;
use std::time::Duration;

use super::ServerTls;

/// How often the files are checked for changes.
pub const RELOAD_POLL: Duration = Duration::from_secs(5);

/// Watches `tls`'s files until the process ends.
pub async fn watch_and_reload(tls: Arc<ServerTls>) {
    let mut hangup = match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::hangup()) {
        Ok(s) => Some(s),
        Err(err) => {
            tracing::warn!(%err, "no SIGHUP handler: TLS files are reloaded only when they change");
            None
        }
    };
    loop {
        let why = tokio::select! {
            Some(()) = async { match hangup.as_mut() { Some(h) => h.recv().await, None => None } } => "SIGHUP",
            () = tokio::time::sleep(RELOAD_POLL) => {
                if !tls.changed_on_disk() {
                    continue;
                }
                "a TLS file changed"
            }
        };
        match tls.reload() {
            Ok(()) => tracing::info!(cause = why, cert = %tls.files.cert.display(), "TLS certificates reloaded: new connections use them"),
            Err(err) => tracing::warn!(cause = why, error = %err, "TLS reload failed: still serving the previous certificates"),
        }
    }
}
