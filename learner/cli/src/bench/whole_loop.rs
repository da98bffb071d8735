//! `learner bench loop`: a learner in this process and actor processes beside it, measured as a
//! whole (env steps, updates, weight lag, the learner's idle time).

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use super::machine::{cpu_model, gemm_peak_gflops, load_average, update_flops};
use agent::config::{Durability, RunConfig};
use agent::fastnet::Precision;
use learner::serve::{ServeOptions, start};

/// Runs a learner here (default configuration, so the paper network at the default camera) and
/// `actors` actor processes (the `actor` program next to this one) for `seconds`, and measures
/// what they produce: environment steps per second, updates per second, and the mean lag
/// between the newest weights and the weights actors act with (sampled every second).
///
/// Without `train`, the learner only ingests (its replay never reaches its minimum): the actors'
/// own rate with nothing else on the cores.
///
/// `precision` is the run's `[agent] precision` (learner and actors alike).
pub async fn whole_loop(
    actors: usize,
    envs: usize,
    seconds: f64,
    train: bool,
    durability: Durability,
    precision: Precision,
) -> Result<serde_json::Value> {
    let chosen = precision.resolve().with_context(|| format!("--precision {}", precision.name()))?;
    let exe = std::env::current_exe()?;
    let actor_exe = exe.with_file_name(if cfg!(windows) { "actor.exe" } else { "actor" });
    if !actor_exe.exists() {
        bail!("the actor program is not next to this one ({}): build it with `cargo build --release -p actor`", actor_exe.display());
    }
    let load_before = load_average();
    let threads = agent::fastnet::default_threads();
    let peak = gemm_peak_gflops(threads, 5);
    let mut cfg = RunConfig::default();
    cfg.service.durability = durability;
    cfg.agent.precision = precision;
    if !train {
        cfg.agent.min_replay = cfg.agent.replay_capacity;
    }
    let dir = std::env::temp_dir().join(format!("learner-bench-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    let cfg_path = dir.join("bench.toml");
    std::fs::write(&cfg_path, cfg.to_toml())?;
    let running = start(ServeOptions {
        config: Some(cfg_path),
        listen: Some("127.0.0.1:0".into()),
        run_dir: Some(dir.join("run")),
        ..ServeOptions::default()
    })
    .await?;
    let addr = running.addr.to_string();
    let mut children = Vec::new();
    for k in 0..actors {
        children.push(
            std::process::Command::new(&actor_exe)
                .args(["--learner", &addr, "--envs", &envs.to_string(), "--name", &format!("bench-{k}"), "--seed", &k.to_string()])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .with_context(|| format!("starting {}", actor_exe.display()))?,
        );
    }
    // Warm-up: until every actor has delivered something.
    let warm = Instant::now();
    while running.shared.actors.lock().expect("actors lock").iter().filter(|a| a.transitions > 0).count() < actors {
        if warm.elapsed() > Duration::from_secs(120) {
            bail!("actors did not start streaming within 120 s");
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let counters = |r: &learner::serve::Running| {
        let c = r.shared.counters.lock().expect("counters lock");
        (c.env_steps, c.learner_step, r.shared.stats.lock().expect("stats lock").idle_secs)
    };
    let (s0, u0, idle0) = counters(&running);
    let t0 = Instant::now();
    let mut lags = Vec::new();
    while t0.elapsed().as_secs_f64() < seconds {
        tokio::time::sleep(Duration::from_secs(1)).await;
        let st = learner::service::status(&running.shared);
        lags.extend(st.actors.iter().filter(|a| a.connected).map(|a| a.version_lag as f64));
        tracing::info!(secs = t0.elapsed().as_secs(), env_steps = st.transitions_received, updates = st.learner_step, "benchmarking");
    }
    let (s1, u1, idle1) = counters(&running);
    let secs = t0.elapsed().as_secs_f64();
    for c in &mut children {
        let _ = c.kill();
        let _ = c.wait();
    }
    running.stop().await?;
    let _ = std::fs::remove_dir_all(&dir);
    let mean_lag = if lags.is_empty() { 0.0 } else { lags.iter().sum::<f64>() / lags.len() as f64 };
    let (steps_per_sec, updates_per_sec) = ((s1 - s0) as f64 / secs, (u1 - u0) as f64 / secs);
    // The arithmetic the run did: one forward pass per environment step, and the updates'.
    let shape = cfg.net_shape();
    let gflops =
        (steps_per_sec * shape.forward_flops() + updates_per_sec * update_flops(&shape, cfg.agent.batch_size, cfg.agent.double_dqn)) / 1e9;
    Ok(serde_json::json!({
        "env_steps_per_sec": steps_per_sec,
        "updates_per_sec": updates_per_sec,
        "gflops": gflops,
        "peak_gflops": peak,
        "fraction_of_peak": gflops / peak,
        "threads": threads,
        "cpu": cpu_model(),
        "mean_weight_lag": mean_lag,
        "learner_idle_fraction": ((idle1 - idle0) / secs).clamp(0.0, 1.0),
        "replay_ratio": cfg.agent.replay_ratio,
        "training": train,
        "precision": if chosen.bf16 { "bf16" } else { "f32" },
        "load_before": load_before,
        "load_after": load_average(),
        "actors": actors,
        "envs_per_actor": envs,
        "durability": durability.name(),
    }))
}
