//! `learner status`: asks a learner for its status and prints it, readable or as JSON.

use anyhow::{Context, Result};
use proto::v1 as pb;
use proto::v1::learner_client::LearnerClient;
use serde_json::json;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Channel, Endpoint};

/// A client of the learner service that sends the auth token, if any.
pub type Client = LearnerClient<InterceptedService<Channel, TokenInterceptor>>;

/// Connects to a learner at `addr` (`host:port` or `http://host:port`), with an optional token.
pub async fn connect(addr: &str, token: Option<String>) -> Result<Client> {
    let url = if addr.starts_with("http://") || addr.starts_with("https://") { addr.to_owned() } else { format!("http://{addr}") };
    let channel = Endpoint::from_shared(url.clone())
        .with_context(|| format!("`{addr}` is not a valid address (expected host:port)"))?
        .connect_timeout(std::time::Duration::from_secs(5))
        .initial_stream_window_size(Some(crate::serve::STREAM_WINDOW))
        .initial_connection_window_size(Some(crate::serve::CONNECTION_WINDOW))
        // A silently dead path (a cut network, a peer that moved) is noticed within ~30 s, not
        // after TCP's own retransmission timeout of many minutes, so actors reconnect.
        .http2_keep_alive_interval(std::time::Duration::from_secs(10))
        .keep_alive_timeout(std::time::Duration::from_secs(20))
        .keep_alive_while_idle(true)
        .connect()
        .await
        .with_context(|| format!("connecting to the learner at {url}"))?;
    Ok(LearnerClient::with_interceptor(channel, TokenInterceptor(token))
        .max_decoding_message_size(256 << 20)
        .max_encoding_message_size(256 << 20))
}

/// Adds `authorization: Bearer TOKEN` to every call when a token is set.
#[derive(Debug, Clone)]
pub struct TokenInterceptor(pub Option<String>);

impl tonic::service::Interceptor for TokenInterceptor {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(t) = &self.0 {
            let v = format!("Bearer {t}")
                .parse()
                .map_err(|_| tonic::Status::invalid_argument("the auth token has characters not allowed in a header"))?;
            req.metadata_mut().insert("authorization", v);
        }
        Ok(req)
    }
}

/// The status as a JSON value (the `--json` output).
#[must_use]
pub fn to_json(s: &pb::StatusResponse) -> serde_json::Value {
    let ep = s.episodes.unwrap_or_default();
    let finite = |x: f64| if x.is_finite() { json!(x) } else { serde_json::Value::Null };
    json!({
        "run_id": s.run_id,
        "variant": s.variant,
        "uptime_secs": s.uptime_secs,
        "learner_step": s.learner_step,
        "weights_version": s.weights_version,
        "transitions_received": s.transitions_received,
        "transitions_stored": s.transitions_stored,
        "transitions_rejected": s.transitions_rejected,
        "batches_rejected": s.batches_rejected,
        "replay_size": s.replay_size,
        "replay_capacity": s.replay_capacity,
        "replay_bytes": s.replay_bytes,
        "updates_per_sec": s.updates_per_sec,
        "env_steps_per_sec": s.env_steps_per_sec,
        "loss": finite(s.loss),
        "mean_q": finite(s.mean_q),
        "epsilon": s.epsilon,
        "episodes": {
            "total": ep.episodes_total,
            "window": ep.window,
            "mean_return": ep.mean_return,
            "completion_rate": ep.completion_rate,
            "collision_rate": ep.collision_rate,
        },
        "actors": s.actors.iter().map(|a| json!({
            "actor_id": a.actor_id,
            "name": a.name,
            "actor_index": a.actor_index,
            "connected": a.connected,
            "last_seen_secs": a.last_seen_secs,
            "weights_version": a.weights_version,
            "version_lag": a.version_lag,
            "transitions": a.transitions,
            "rejected_batches": a.rejected_batches,
        })).collect::<Vec<_>>(),
    })
}

/// Prints the status readably.
pub fn print_table(s: &pb::StatusResponse) {
    let ep = s.episodes.unwrap_or_default();
    println!("run {} ({}), up {:.0} s", s.run_id, s.variant, s.uptime_secs);
    println!(
        "learner step {}   weights version {}   updates/s {:.2}   env steps/s {:.0}",
        s.learner_step, s.weights_version, s.updates_per_sec, s.env_steps_per_sec
    );
    println!("loss {:.4}   mean Q {:.3}   epsilon {:.3}", s.loss, s.mean_q, s.epsilon);
    println!(
        "replay {}/{} transitions, {:.1} MiB   received {}   stored {}   rejected {} ({} batches)",
        s.replay_size,
        s.replay_capacity,
        s.replay_bytes as f64 / (1 << 20) as f64,
        s.transitions_received,
        s.transitions_stored,
        s.transitions_rejected,
        s.batches_rejected
    );
    println!(
        "episodes {} — last {}: mean return {:.2}, completed {:.0}%, collided {:.0}%",
        ep.episodes_total,
        ep.window,
        ep.mean_return,
        100.0 * ep.completion_rate,
        100.0 * ep.collision_rate
    );
    println!(
        "{:<34} {:<12} {:>5} {:>9} {:>10} {:>7} {:>12} {:>8}",
        "actor", "name", "index", "connected", "last seen", "lag", "transitions", "rejected"
    );
    for a in &s.actors {
        println!(
            "{:<34} {:<12} {:>5} {:>9} {:>9.1}s {:>7} {:>12} {:>8}",
            a.actor_id, a.name, a.actor_index, a.connected, a.last_seen_secs, a.version_lag, a.transitions, a.rejected_batches
        );
    }
}
