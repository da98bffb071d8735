//! `learner bench loop`: a learner in this process and actor processes beside it, measured as a
//! whole (env steps, updates, weight lag, the learner's idle time).

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use super::machine::{cpu_model, gemm_peak_gflops, load_average, update_flops};
use agent::config::{Durability, RunConfig};
use agent::fastnet::Precision;
use learner::serve::{ServeOptions, start};

/// The run configuration of `learner bench loop`: `preset`'s, or `file`'s (as `learner serve
/// --config` reads it; a file may start from a preset), or the default configuration; then
/// `durability`, `precision` and `replay_ratio` where given (`[service] durability`, `[agent]
/// precision` and `[agent] replay_ratio`), and without `train` a replay minimum the run never
/// reaches. The result is validated.
pub fn loop_config(
    preset: Option<&str>,
    file: Option<&Path>,
    durability: Option<Durability>,
    precision: Option<Precision>,
    replay_ratio: Option<f32>,
    train: bool,
) -> Result<RunConfig> {
    let mut cfg = match (preset, file) {
        (Some(_), Some(_)) => bail!("--preset and --config exclude each other"),
        (Some(name), None) => RunConfig::preset(name).map_err(|e| anyhow::anyhow!("--preset: {e}"))?,
        (None, Some(path)) => RunConfig::load(path)?,
        (None, None) => RunConfig::default(),
    };
    if let Some(d) = durability {
        cfg.service.durability = d;
    }
    if let Some(p) = precision {
        cfg.agent.precision = p;
    }
    if let Some(r) = replay_ratio {
        cfg.agent.replay_ratio = r;
    }
    if !train {
        cfg.agent.min_replay = cfg.agent.replay_capacity;
    }
    cfg.validate().map_err(|(field, message)| anyhow::anyhow!("the benchmark's configuration: field `{field}`: {message}"))?;
    Ok(cfg)
}

/// Samples trained per environment step over a window: `updates` updates of `batch_size`
/// transitions each, over the `stored` transitions the replay took in meanwhile (what `[agent]
/// replay_ratio` asks for when the learner keeps up; below it when the learner falls behind).
/// 0 when nothing was stored.
#[must_use]
pub fn effective_replay_ratio(updates: u64, batch_size: usize, stored: u64) -> f64 {
    if stored == 0 { 0.0 } else { updates as f64 * batch_size as f64 / stored as f64 }
}

/// Runs a learner here with `cfg` (see [`loop_config`]; the default configuration is the paper
/// network at the default camera) and `actors` actor processes (the `actor` program next to this
/// one; they take their environment and agent from the learner) for `seconds`, and measures what
/// they produce: environment steps per second, updates per second, samples trained per
/// environment step, and the mean lag between the newest weights and the weights actors act with
/// (sampled every second).
///
/// Without `train`, the learner only ingests (its replay never reaches its minimum; `cfg` says so
/// already): the actors' own rate with nothing else on the cores.
pub async fn whole_loop(actors: usize, envs: usize, seconds: f64, train: bool, cfg: RunConfig) -> Result<serde_json::Value> {
    let precision = cfg.agent.precision;
    let durability = cfg.service.durability;
    let chosen = precision.resolve().with_context(|| format!("[agent] precision {}", precision.name()))?;
    let exe = std::env::current_exe()?;
    let actor_exe = exe.with_file_name(if cfg!(windows) { "actor.exe" } else { "actor" });
    if !actor_exe.exists() {
        bail!("the actor program is not next to this one ({}): build it with `cargo build --release -p actor`", actor_exe.display());
    }
    let load_before = load_average();
    let threads = agent::fastnet::default_threads();
    let peak = gemm_peak_gflops(threads, 5);
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
        (c.env_steps, c.learner_step, c.transitions_stored, r.shared.stats.lock().expect("stats lock").idle_secs)
    };
    let (s0, u0, stored0, idle0) = counters(&running);
    let t0 = Instant::now();
    let mut lags = Vec::new();
    while t0.elapsed().as_secs_f64() < seconds {
        tokio::time::sleep(Duration::from_secs(1)).await;
        let st = learner::service::status(&running.shared);
        lags.extend(st.actors.iter().filter(|a| a.connected).map(|a| a.version_lag as f64));
        tracing::info!(secs = t0.elapsed().as_secs(), env_steps = st.transitions_received, updates = st.learner_step, "benchmarking");
    }
    let (s1, u1, stored1, idle1) = counters(&running);
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
        "effective_replay_ratio": effective_replay_ratio(u1 - u0, cfg.agent.batch_size, stored1 - stored0),
        "preset": cfg.preset,
        "training": train,
        "precision": if chosen.bf16 { "bf16" } else { "f32" },
        "load_before": load_before,
        "load_after": load_average(),
        "actors": actors,
        "envs_per_actor": envs,
        "durability": durability.name(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_configuration_starts_from_a_preset_or_a_file_and_takes_the_overrides() {
        let default = loop_config(None, None, None, None, None, true).unwrap();
        assert_eq!(default, RunConfig::default());
        let paper = loop_config(Some("paper"), None, Some(Durability::None), None, Some(2.0), true).unwrap();
        let mut expected = RunConfig::preset("paper").unwrap();
        (expected.service.durability, expected.agent.replay_ratio) = (Durability::None, 2.0);
        assert_eq!(paper, expected);
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("run.toml");
        std::fs::write(&file, "preset = \"hybrid-tuned\"\n[agent]\nbatch_size = 16\n").unwrap();
        let from_file = loop_config(None, Some(file.as_path()), None, Some(Precision::F32), None, false).unwrap();
        assert_eq!(from_file.preset.as_deref(), Some("hybrid-tuned"));
        assert_eq!((from_file.agent.batch_size, from_file.agent.precision), (16, Precision::F32));
        assert_eq!(from_file.agent.min_replay, from_file.agent.replay_capacity, "ingest only");
    }

    #[test]
    fn bad_choices_are_named() {
        let err = |r: Result<RunConfig>| format!("{:#}", r.unwrap_err());
        assert!(err(loop_config(Some("no-such"), None, None, None, None, true)).starts_with("--preset: "));
        assert!(err(loop_config(Some("paper"), Some(Path::new("x.toml")), None, None, None, true)).contains("exclude each other"));
        assert!(err(loop_config(None, None, None, None, Some(0.0), true)).contains("replay_ratio"));
        assert!(err(loop_config(None, Some(Path::new("/nonexistent/run.toml")), None, None, None, true)).contains("/nonexistent/run.toml"));
    }

    #[test]
    fn the_effective_ratio_is_samples_trained_per_stored_step() {
        assert_eq!(effective_replay_ratio(10, 32, 1280), 0.25);
        assert_eq!(effective_replay_ratio(0, 32, 500), 0.0);
        assert_eq!(effective_replay_ratio(3, 32, 0), 0.0);
    }
}
