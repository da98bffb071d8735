//! The Prometheus text exposition of the learner's state, served over HTTP on
//! `--metrics-listen`.

use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::state::Shared;

/// The Prometheus text exposition of the learner's state.
#[must_use]
pub fn prometheus_text(shared: &Shared) -> String {
    let c = shared.counters.lock().expect("counters lock").clone();
    let s = *shared.stats.lock().expect("stats lock");
    let (replay_size, replay_bytes) = {
        let r = shared.replay.lock().expect("replay lock");
        (r.len(), r.bytes())
    };
    let actors = shared.actors.lock().expect("actors lock");
    let timeout = shared.cfg.service.actor_timeout_secs as f64;
    let connected = actors.iter().filter(|a| a.last_seen.elapsed().as_secs_f64() < timeout).count();
    let mut out = String::new();
    let mut metric = |name: &str, kind: &str, help: &str, value: f64| {
        out.push_str(&format!("# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {value}\n"));
    };
    metric("learner_updates_total", "counter", "DQN updates done.", c.learner_step as f64);
    metric("learner_env_steps_total", "counter", "Environment steps received.", c.env_steps as f64);
    metric("learner_transitions_received_total", "counter", "Transitions received from actors.", c.transitions_received as f64);
    metric("learner_transitions_stored_total", "counter", "Transitions stored in replay.", c.transitions_stored as f64);
    metric("learner_transitions_rejected_total", "counter", "Transitions rejected as invalid.", c.transitions_rejected as f64);
    metric("learner_batches_rejected_total", "counter", "Batches rejected as invalid.", c.batches_rejected as f64);
    metric("learner_episodes_total", "counter", "Episodes finished by actors.", c.episodes as f64);
    metric("learner_weights_version", "gauge", "Version of the newest published weights.", c.weights_version as f64);
    metric("learner_replay_size", "gauge", "Transitions in replay.", replay_size as f64);
    metric("learner_replay_bytes", "gauge", "Bytes used by replay.", replay_bytes as f64);
    metric("learner_updates_per_second", "gauge", "Recent DQN updates per second.", s.updates_per_sec);
    metric("learner_env_steps_per_second", "gauge", "Recent environment steps per second.", s.env_steps_per_sec);
    metric("learner_loss", "gauge", "Recent mean Huber loss.", s.loss.unwrap_or(f64::NAN));
    metric("learner_mean_q", "gauge", "Recent mean Q of the actions taken.", s.mean_q.unwrap_or(f64::NAN));
    metric("learner_epsilon", "gauge", "Exploration rate of the schedule.", s.epsilon);
    metric("learner_actors_connected", "gauge", "Actors seen within the timeout.", connected as f64);
    metric("learner_uptime_seconds", "gauge", "Seconds since this learner process started.", shared.started.elapsed().as_secs_f64());
    out
}

/// Serves the Prometheus text on every HTTP request to `listener` until the process ends.
pub async fn serve_prometheus(listener: tokio::net::TcpListener, shared: std::sync::Arc<Shared>) {
    loop {
        let Ok((mut sock, _)) = listener.accept().await else { continue };
        let shared = shared.clone();
        tokio::spawn(async move {
            // Read (and ignore) the request head; answer with the metrics whatever the path.
            let mut buf = [0u8; 2048];
            let _ = tokio::time::timeout(std::time::Duration::from_secs(2), sock.read(&mut buf)).await;
            let body = prometheus_text(&shared);
            let head = format!(
                "HTTP/1.1 200 OK\r\nContent-Type: text/plain; version=0.0.4\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                body.len()
            );
            let _ = sock.write_all(head.as_bytes()).await;
            let _ = sock.write_all(body.as_bytes()).await;
            let _ = sock.shutdown().await;
        });
    }
}
