//! Accepting TLS: TCP connections are taken as they come and each handshake runs in its own
//! task, bounded by [`HANDSHAKE_TIMEOUT`], so that a slow or silent peer (or plaintext sent to
//! this port) holds up no one else. Finished streams go to the server through a channel; refused
//! handshakes are logged with the peer and rustls' reason.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_rustls::server::TlsStream;

use super::{Alpn, ServerTls};

/// How long a client may take to finish the TLS handshake.
pub const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);

/// Accepts on `listener` with `tls`'s current configuration for `alpn`, until the receiver is
/// dropped.
pub fn accept_tls(listener: TcpListener, tls: Arc<ServerTls>, alpn: Alpn) -> mpsc::Receiver<(TlsStream<TcpStream>, SocketAddr)> {
    let (tx, rx) = mpsc::channel(64);
    tokio::spawn(async move {
        loop {
            let accepted = tokio::select! {
                () = tx.closed() => return,
                a = listener.accept() => a,
            };
            let (tcp, peer) = match accepted {
                Ok(a) => a,
                Err(err) => {
                    // Out of file descriptors and the like: wait, do not spin.
                    tracing::warn!(%err, "accepting a connection");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            };
            let _ = tcp.set_nodelay(true);
            let acceptor = tokio_rustls::TlsAcceptor::from(tls.current(alpn));
            let tx = tx.clone();
            tokio::spawn(async move {
                match tokio::time::timeout(HANDSHAKE_TIMEOUT, acceptor.accept(tcp)).await {
                    Ok(Ok(stream)) => {
                        let _ = tx.send((stream, peer)).await;
                    }
                    Ok(Err(err)) => tracing::warn!(%peer, reason = %err, "TLS handshake refused"),
                    Err(_) => tracing::warn!(%peer, "TLS handshake not finished within {} s: closed", HANDSHAKE_TIMEOUT.as_secs()),
                }
            });
        }
    });
    rx
}

/// TLS connections as axum's listener (the metrics endpoint).
#[derive(Debug)]
pub struct TlsListener {
    pub connections: mpsc::Receiver<(TlsStream<TcpStream>, SocketAddr)>,
    pub local: SocketAddr,
}

impl axum::serve::Listener for TlsListener {
    type Io = TlsStream<TcpStream>;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        match self.connections.recv().await {
            Some(c) => c,
            // The acceptor is gone (it ends only with the runtime): nothing more will come.
            None => std::future::pending().await,
        }
    }

    fn local_addr(&self) -> std::io::Result<Self::Addr> {
        Ok(self.local)
    }
}
