//! The learner's metrics for Prometheus, encoded by `prometheus-client` (the Prometheus project's
//! Rust client) and served at `/metrics` on `--metrics-listen` by axum — the HTTP stack tonic
//! already compiles in. Values are read from the shared state at each scrape (a [`Collector`]), so
//! nothing is kept twice. Dashboards (`deploy/grafana/`) and alerts use these names.

use std::sync::Arc;

use axum::http::header;
use axum::response::IntoResponse;
use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric};
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::registry::Registry;

use crate::state::Shared;

/// Reads the learner's state at every scrape.
#[derive(Debug)]
struct LearnerCollector(Arc<Shared>);

impl Collector for LearnerCollector {
    fn encode(&self, mut enc: DescriptorEncoder) -> Result<(), std::fmt::Error> {
        let shared = &self.0;
        let c = shared.counters.lock().expect("counters lock").clone();
        let s = *shared.stats.lock().expect("stats lock");
        let (replay_size, replay_bytes) = {
            let r = shared.replay.lock().expect("replay lock");
            (r.len() as i64, r.bytes() as i64)
        };
        let status = crate::service::status(shared);
        let episodes = status.episodes.unwrap_or_default();
        let connected: Vec<_> = status.actors.iter().filter(|a| a.connected).collect();
        let mean_lag = if connected.is_empty() {
            f64::NAN
        } else {
            connected.iter().map(|a| a.version_lag as f64).sum::<f64>() / connected.len() as f64
        };

        // Counters: the encoder adds `_total` to each name.
        for (name, help, value) in [
            ("learner_updates", "DQN updates done.", c.learner_step),
            ("learner_env_steps", "Environment steps received.", c.env_steps),
            ("learner_transitions_received", "Transitions received from actors.", c.transitions_received),
            ("learner_transitions_stored", "Transitions stored in replay.", c.transitions_stored),
            ("learner_transitions_rejected", "Transitions rejected as invalid.", c.transitions_rejected),
            ("learner_batches_rejected", "Batches rejected as invalid.", c.batches_rejected),
            ("learner_episodes", "Episodes finished by actors.", c.episodes),
        ] {
            let m = ConstCounter::new(value);
            m.encode(enc.encode_descriptor(name, help, None, m.metric_type())?)?;
        }
        for (name, help, value) in [
            ("learner_weights_version", "Version of the newest published weights.", c.weights_version as i64),
            ("learner_replay_size", "Transitions in replay.", replay_size),
            ("learner_replay_bytes", "Bytes used by replay.", replay_bytes),
            ("learner_actors_connected", "Actors with an open experience stream, heard from within the timeout.", connected.len() as i64),
        ] {
            let m = ConstGauge::new(value);
            m.encode(enc.encode_descriptor(name, help, None, m.metric_type())?)?;
        }
        for (name, help, value) in [
            ("learner_updates_per_second", "DQN updates per second over the last 10 s.", s.updates_per_sec),
            ("learner_env_steps_per_second", "Environment steps per second over the last 10 s.", s.env_steps_per_sec),
            ("learner_loss", "Recent mean Huber loss (NaN before training).", s.loss.unwrap_or(f64::NAN)),
            ("learner_mean_q", "Recent mean Q of the actions taken (NaN before training).", s.mean_q.unwrap_or(f64::NAN)),
            ("learner_epsilon", "Exploration rate of the schedule at the run's environment steps.", status.epsilon),
            ("learner_episode_return_mean", "Mean return of the recent episodes (service.stats_window).", episodes.mean_return),
            ("learner_episode_completion_rate", "Share of the recent episodes that reached their goal.", episodes.completion_rate),
            ("learner_episode_collision_rate", "Share of the recent episodes that ended in a collision.", episodes.collision_rate),
            ("learner_weights_lag_mean", "Mean versions the connected actors' weights are behind (NaN without actors).", mean_lag),
            ("learner_uptime_seconds", "Seconds since this learner process started.", shared.started.elapsed().as_secs_f64()),
            ("learner_run_seconds", "Seconds the run has trained, over all its sessions.", shared.run_secs()),
        ] {
            let m = ConstGauge::new(value);
            m.encode(enc.encode_descriptor(name, help, None, m.metric_type())?)?;
        }
        // Per actor: how far behind its weights are.
        let m = ConstGauge::new(0i64);
        let mut family = enc.encode_descriptor(
            "learner_actor_weights_lag",
            "Versions an actor's weights are behind the newest (connected actors).",
            None,
            m.metric_type(),
        )?;
        for a in &connected {
            let labels = [("actor", a.name.as_str())];
            ConstGauge::new(a.version_lag as i64).encode(family.encode_family(&labels)?)?;
        }
        // Per actor: the exploration rate it acts with (its last acknowledged batch).
        let m = ConstGauge::new(0f64);
        let mut family = enc.encode_descriptor(
            "learner_actor_epsilon",
            "Exploration rate of an actor's last batch (connected actors).",
            None,
            m.metric_type(),
        )?;
        for a in &connected {
            let labels = [("actor", a.name.as_str())];
            ConstGauge::new(f64::from(a.epsilon)).encode(family.encode_family(&labels)?)?;
        }
        Ok(())
    }
}

/// A registry holding the learner's metrics.
#[must_use]
pub fn registry(shared: Arc<Shared>) -> Registry {
    let mut registry = Registry::default();
    registry.register_collector(Box::new(LearnerCollector(shared)));
    registry
}

/// The Prometheus text exposition (format 0.0.4) of the learner's state.
#[must_use]
pub fn prometheus_text(registry: &Registry) -> String {
    let mut out = String::new();
    prometheus_client::encoding::prometheus_text::encode(&mut out, registry).expect("writing to a String cannot fail");
    out
}

/// Serves `/metrics` over HTTP on `listener` (TCP, or TLS connections) until the process ends.
pub async fn serve_prometheus<L>(listener: L, shared: Arc<Shared>)
where
    L: axum::serve::Listener,
    L::Addr: std::fmt::Debug,
{
    let registry = Arc::new(registry(shared));
    let metrics = move || {
        let registry = registry.clone();
        async move {
            (
                [
                    (header::CONTENT_TYPE, prometheus_client::encoding::prometheus_text::CONTENT_TYPE),
                    // One scrape per connection: scrapers reconnect every interval anyway, and
                    // simple clients (nc, a raw socket) see the end of the answer.
                    (header::CONNECTION, "close"),
                ],
                prometheus_text(&registry),
            )
                .into_response()
        }
    };
    let app = axum::Router::new().route("/metrics", axum::routing::get(metrics));
    if let Err(err) = axum::serve(listener, app).await {
        tracing::warn!(%err, "the metrics server stopped");
    }
}
