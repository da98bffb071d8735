//! The learner's Prometheus endpoint over real HTTP on 127.0.0.1:0: the text format, every metric
//! the Grafana dashboard (deploy/grafana/) uses, per-actor series, and a 404 elsewhere.
//! (`tests/interop/test_deploy.py` parses the same endpoint with Prometheus' own Python parser.)

use agent::config::RunConfig;
use learner::serve::{ServeOptions, start};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

async fn get(addr: &str, path: &str) -> String {
    let mut sock = tokio::net::TcpStream::connect(addr).await.unwrap();
    sock.write_all(format!("GET {path} HTTP/1.1\r\nHost: learner\r\nConnection: close\r\n\r\n").as_bytes()).await.unwrap();
    let mut answer = String::new();
    sock.read_to_string(&mut answer).await.unwrap();
    answer
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_are_served_in_the_prometheus_text_format() {
    let dir = tempfile::tempdir().unwrap();
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&dir.path().join("run")).to_toml()).unwrap();
    let running = start(ServeOptions { config: Some(cfg_path), metrics_listen: Some("127.0.0.1:0".into()), ..ServeOptions::default() })
        .await
        .unwrap();
    let mut c = proto::client::connect(&running.addr.to_string(), None).await.unwrap();
    c.register(proto::v1::RegisterRequest { name: "fake".into(), envs: 1, protocol: 1, ..Default::default() }).await.unwrap();

    let addr = std::fs::read_to_string(dir.path().join("run/metrics.addr")).unwrap();
    let answer = get(addr.trim(), "/metrics").await;
    let (head, body) = answer.split_once("\r\n\r\n").unwrap();
    assert!(head.starts_with("HTTP/1.1 200 OK"), "{head}");
    assert!(head.to_ascii_lowercase().contains("content-type: text/plain; version=0.0.4"), "{head}");
    assert!(body.contains("# TYPE learner_updates_total counter\nlearner_updates_total 0\n"), "{body}");
    assert!(body.contains("# TYPE learner_loss gauge\nlearner_loss NaN\n"), "{body}");
    // Registered but streaming nothing: not connected (`connected` means an open experience stream).
    assert!(body.contains("learner_actors_connected 0\n"), "{body}");
    // The per-actor family is declared; its series are the connected actors' (none here).
    assert!(body.contains("# TYPE learner_actor_weights_lag gauge\n"), "{body}");
    assert!(!body.contains("learner_actor_weights_lag{actor=\"fake\"} "), "{body}");
    for name in [
        "learner_env_steps_total",
        "learner_episodes_total",
        "learner_updates_per_second",
        "learner_env_steps_per_second",
        "learner_mean_q",
        "learner_episode_return_mean",
        "learner_episode_completion_rate",
        "learner_weights_lag_mean",
        "learner_replay_size",
        "learner_weights_version",
        "learner_run_seconds",
    ] {
        assert!(body.contains(&format!("\n{name} ")), "{name} missing:\n{body}");
    }
    assert!(get(addr.trim(), "/").await.starts_with("HTTP/1.1 404"));
    running.stop().await.unwrap();
}
