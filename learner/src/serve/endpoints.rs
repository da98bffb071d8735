//! The learner's listeners: the gRPC service (with health, token authentication and the services
//! the program adds, such as reflection) and the Prometheus endpoint, over TLS when it is configured; and the addresses they bind.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};
use proto::v1::learner_server::LearnerServer;
use tonic::codec::CompressionEncoding;

use super::run_dir::{ADDR_FILE, METRICS_ADDR_FILE};
use crate::service::LearnerService;
use crate::service::tls::{Alpn, ServerTls, ServerTlsFiles};
use crate::shared_state::Shared;
use crate::telemetry::prometheus::serve_prometheus;
use agent::config::RunConfig;

/// The gRPC server's task, stopped by sending on its channel.
pub(super) type GrpcServer = tokio::task::JoinHandle<Result<(), tonic::transport::Error>>;

/// Resolves `host:port` or `http://host:port` to a socket address; a bare port is loopback's.
pub async fn resolve(addr: &str) -> Result<SocketAddr> {
    if let Ok(port) = addr.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    let bare = addr.trim_start_matches("http://").trim_start_matches("https://").trim_end_matches('/');
    tokio::net::lookup_host(bare)
        .await
        .with_context(|| format!("resolving address `{addr}` (expected host:port, e.g. 127.0.0.1:50051)"))?
        .next()
        .with_context(|| format!("address `{addr}` resolved to nothing"))
}

/// The server's TLS from `[service]` (after the flags), or `None` for plaintext.
pub(super) fn server_tls(s: &agent::config::ServiceConfig) -> Result<Option<Arc<ServerTls>>> {
    if s.tls_cert.is_empty() {
        return Ok(None);
    }
    let files = ServerTlsFiles {
        cert: s.tls_cert.clone().into(),
        key: s.tls_key.clone().into(),
        client_ca: (!s.tls_client_ca.is_empty()).then(|| s.tls_client_ca.clone().into()),
    };
    Ok(Some(ServerTls::load(files)?))
}

/// One WARN when `what` listens beyond loopback in clear.
fn warn_if_in_clear(what: &str, addr: SocketAddr, tls: bool) {
    if !tls && !addr.ip().is_loopback() {
        tracing::warn!(
            %addr,
            "{what} listens on a non-loopback address without TLS: tokens, experience and weights cross the network in clear; \
             serve TLS with --tls-cert FILE --tls-key FILE (and --tls-client-ca FILE for mutual TLS; `learner certs` makes them)"
        );
    }
}

/// Serves Prometheus metrics at `listen` (a bare port is loopback's), writing the bound address
/// to the run directory.
pub(super) async fn serve_metrics(listen: &str, run_dir: &Path, tls: Option<&Arc<ServerTls>>, shared: &Arc<Shared>) -> Result<()> {
    let addr = resolve(listen).await?;
    let listener = tokio::net::TcpListener::bind(addr).await.with_context(|| format!("binding metrics address {addr}"))?;
    let local = listener.local_addr()?;
    std::fs::write(run_dir.join(METRICS_ADDR_FILE), local.to_string())?;
    warn_if_in_clear("the metrics endpoint (--metrics-listen)", local, tls.is_some());
    match tls {
        Some(t) => {
            tracing::info!(addr = %local, "Prometheus metrics at https://{local}/metrics");
            let connections = crate::service::tls::accept_tls(listener, t.clone(), Alpn::Http1);
            tokio::spawn(serve_prometheus(crate::service::tls::TlsListener { connections, local }, shared.clone()));
        }
        None => {
            tracing::info!(addr = %local, "Prometheus metrics at http://{local}/metrics");
            tokio::spawn(serve_prometheus(listener, shared.clone()));
        }
    }
    Ok(())
}

/// Binds `service.listen` and serves the learner, health and `extra` on it; the bound address
/// (also written to the run directory), the stop channel and the server's task.
pub(super) async fn serve_grpc(
    cfg: &RunConfig,
    run_dir: &Path,
    tls: Option<&Arc<ServerTls>>,
    token: Option<String>,
    shared: &Arc<Shared>,
    extra: Option<tonic::service::Routes>,
) -> Result<(SocketAddr, tokio::sync::oneshot::Sender<()>, GrpcServer)> {
    let addr = resolve(&cfg.service.listen).await?;
    let listener =
        tokio::net::TcpListener::bind(addr).await.with_context(|| format!("binding gRPC address {addr} (service.listen / --listen)"))?;
    let bound = listener.local_addr()?;
    std::fs::write(run_dir.join(ADDR_FILE), bound.to_string())?;
    let max = cfg.service.max_message_bytes;
    let server = LearnerServer::new(LearnerService { shared: shared.clone() })
        .max_decoding_message_size(max)
        .max_encoding_message_size(max)
        .accept_compressed(CompressionEncoding::Zstd)
        .send_compressed(CompressionEncoding::Zstd);
    let svc = tonic::service::interceptor::InterceptedService::new(server, crate::service::auth::interceptor(token));
    let (health_reporter, health) = tonic_health::server::health_reporter();
    health_reporter.set_serving::<LearnerServer<LearnerService>>().await;
    {
        // A learner that cannot go on says so to health checks (the whole server and the
        // learner service), so that orchestrators restart it.
        let shared = shared.clone();
        let reporter = health_reporter.clone();
        tokio::spawn(async move {
            let mut rx = shared.failure.subscribe();
            if rx.wait_for(Option::is_some).await.is_ok() {
                reporter.set_not_serving::<LearnerServer<LearnerService>>().await;
                reporter.set_service_status("", tonic_health::ServingStatus::NotServing).await;
            }
        });
    }
    tracing::info!(addr = %bound, tls = tls.is_some(), mutual_tls = tls.is_some_and(|t| t.mutual()), run_dir = %run_dir.display(), run_id = %shared.run_id, "learner listening");
    warn_if_in_clear("the gRPC service (--listen)", bound, tls.is_some());
    let (stop_server, stopped) = tokio::sync::oneshot::channel::<()>();
    let routes = extra.unwrap_or_default().add_service(health).add_service(svc);
    // Batches of frames are large: HTTP/2's default 64 KiB flow-control window would stall each
    // one on window updates.
    let router = tonic::transport::Server::builder()
        .initial_stream_window_size(Some(proto::client::STREAM_WINDOW))
        .initial_connection_window_size(Some(proto::client::CONNECTION_WINDOW))
        // Streams of actors that vanished without closing (a cut network) end within ~30 s.
        .http2_keepalive_interval(Some(std::time::Duration::from_secs(10)))
        .http2_keepalive_timeout(Some(std::time::Duration::from_secs(20)))
        .add_routes(routes);
    let stopped = async move {
        let _ = stopped.await;
    };
    // Health and the extra services share the listener, and so its TLS.
    let server = match tls {
        Some(t) => {
            use tokio_stream::StreamExt;
            tokio::spawn(crate::service::tls::watch_and_reload(t.clone()));
            let connections = crate::service::tls::accept_tls(listener, t.clone(), Alpn::Grpc);
            let incoming = tokio_stream::wrappers::ReceiverStream::new(connections).map(|(stream, _)| Ok::<_, std::io::Error>(stream));
            tokio::spawn(router.serve_with_incoming_shutdown(incoming, stopped))
        }
        None => tokio::spawn(router.serve_with_incoming_shutdown(tokio_stream::wrappers::TcpListenerStream::new(listener), stopped)),
    };
    Ok((bound, stop_server, server))
}
