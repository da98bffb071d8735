//! The learner's metrics for Prometheus, encoded by `prometheus-client` (the Prometheus project's
//! Rust client) and served at `/metrics` on `--metrics-listen` by axum — the HTTP stack tonic
//! already compiles in. Values are read from the shared state at each scrape (a [`Collector`]), so
//! nothing is kept twice; which fields, under which names, `status_report.rs` says. Dashboards
//! (`deploy/grafana/`) and alerts use these names.

use std::sync::Arc;

use axum::http::header;
use axum::response::IntoResponse;
use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric};
use prometheus_client::metrics::MetricType;
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::registry::Registry;

use crate::shared_state::Shared;
use crate::telemetry::status_report::{ActorReport, EXPORTED, EXPORTED_PER_ACTOR, StatusReport};

/// Reads the learner's state at every scrape.
#[derive(Debug)]
struct LearnerCollector(Arc<Shared>);

/// One metric of `family` read from `value` (a field of the status report's JSON): a `u64` as an
/// integer, anything else as a float, `null` as NaN.
fn encode_value(
    family: prometheus_client::encoding::MetricEncoder<'_>,
    kind: MetricType,
    value: &serde_json::Value,
) -> Result<(), std::fmt::Error> {
    match (kind, value.as_u64()) {
        (MetricType::Counter, Some(n)) => ConstCounter::new(n).encode(family),
        (MetricType::Counter, None) => ConstCounter::new(value.as_f64().unwrap_or(f64::NAN)).encode(family),
        (_, Some(n)) => ConstGauge::new(i64::try_from(n).unwrap_or(i64::MAX)).encode(family),
        (_, None) => ConstGauge::new(value.as_f64().unwrap_or(f64::NAN)).encode(family),
    }
}

impl Collector for LearnerCollector {
    fn encode(&self, mut enc: DescriptorEncoder) -> Result<(), std::fmt::Error> {
        let report = StatusReport::from(crate::service::status(&self.0));
        let json = report.to_json();
        for m in EXPORTED {
            let value = json.pointer(m.field).expect("EXPORTED names fields of the report (tested)");
            encode_value(enc.encode_descriptor(m.name, m.help, None, m.kind)?, m.kind, value)?;
        }

        // Derived from the actors: how many are connected and how far behind they are.
        let connected: Vec<&ActorReport> = report.actors.iter().filter(|a| a.connected).collect();
        let mean_lag = if connected.is_empty() {
            f64::NAN
        } else {
            connected.iter().map(|a| a.version_lag as f64).sum::<f64>() / connected.len() as f64
        };
        let help = "Actors with an open experience stream, heard from within the timeout.";
        ConstGauge::new(connected.len() as i64).encode(enc.encode_descriptor(
            "learner_actors_connected",
            help,
            None,
            MetricType::Gauge,
        )?)?;
        let help = "Mean versions the connected actors' weights are behind (NaN without actors).";
        ConstGauge::new(mean_lag).encode(enc.encode_descriptor("learner_weights_lag_mean", help, None, MetricType::Gauge)?)?;

        // Per connected actor, labelled with its name.
        for m in EXPORTED_PER_ACTOR {
            let mut family = enc.encode_descriptor(m.name, m.help, None, m.kind)?;
            for (a, value) in report.actors.iter().zip(json["actors"].as_array().into_iter().flatten()) {
                if a.connected {
                    let value = value.pointer(m.field).expect("EXPORTED_PER_ACTOR names fields of an actor (tested)");
                    encode_value(family.encode_family(&[("actor", a.name.as_str())])?, m.kind, value)?;
                }
            }
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
