//! `learner health`: asks a learner's standard `grpc.health.v1.Health/Check` and succeeds only
//! when the answer is `SERVING`. Container health checks (`deploy/docker-compose.yml`) use it;
//! it needs no token (the health service is outside the authenticated learner service).

use std::time::Duration;

use anyhow::{Context, Result, bail};
use tonic::transport::Endpoint;
use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_check_response::ServingStatus;
use tonic_health::pb::health_client::HealthClient;

/// Checks `service` (empty: the server as a whole) at `addr` (`host:port` or `http://host:port`),
/// giving up after `timeout` for the connection and again for the call.
pub async fn check(addr: &str, service: &str, timeout: Duration) -> Result<()> {
    let url = if addr.starts_with("http://") || addr.starts_with("https://") { addr.to_owned() } else { format!("http://{addr}") };
    let channel = Endpoint::from_shared(url.clone())
        .with_context(|| format!("`{addr}` is not a valid address (expected host:port)"))?
        .connect_timeout(timeout)
        .timeout(timeout)
        .connect()
        .await
        .with_context(|| format!("connecting to {url}"))?;
    let reply = HealthClient::new(channel)
        .check(HealthCheckRequest { service: service.to_owned() })
        .await
        .map_err(|s| anyhow::anyhow!("grpc.health.v1 Check at {url}: {:?}: {}", s.code(), s.message()))?
        .into_inner();
    let status = ServingStatus::try_from(reply.status).unwrap_or(ServingStatus::Unknown);
    if status != ServingStatus::Serving {
        bail!("{url} reports {} for service `{service}`", status.as_str_name());
    }
    Ok(())
}
