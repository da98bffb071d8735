//! `learner health`: asks a learner's standard `grpc.health.v1.Health/Check` and succeeds only
//! when the answer is `SERVING`. Container health checks (`deploy/docker-compose.yml`) use it;
//! it needs no token (the health service is outside the authenticated learner service), and
//! speaks TLS with `--tls-ca` (and mutual TLS with `--tls-cert`/`--tls-key`), like every client.

use std::time::Duration;

use anyhow::{Result, bail};
use proto::client::Target;
use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_check_response::ServingStatus;
use tonic_health::pb::health_client::HealthClient;

/// Checks `service` (empty: the server as a whole) at `target` (plaintext or TLS), giving up after
/// `timeout` for the connection and again for the call.
pub async fn check(target: &Target, service: &str, timeout: Duration) -> Result<()> {
    let url = &target.url;
    let channel = proto::client::open(target, timeout).await?;
    let mut client = HealthClient::new(channel);
    let call = client.check(HealthCheckRequest { service: service.to_owned() });
    let reply = tokio::time::timeout(timeout, call)
        .await
        .map_err(|_| anyhow::anyhow!("grpc.health.v1 Check at {url}: no answer within {} s", timeout.as_secs_f64()))?
        .map_err(|s| anyhow::anyhow!("grpc.health.v1 Check at {url}: {:?}: {}", s.code(), s.message()))?
        .into_inner();
    let status = ServingStatus::try_from(reply.status).unwrap_or(ServingStatus::Unknown);
    if status != ServingStatus::Serving {
        bail!("{url} reports {} for service `{service}`", status.as_str_name());
    }
    Ok(())
}
