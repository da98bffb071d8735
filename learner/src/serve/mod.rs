//! `learner serve`: loads or resumes a run, starts the training thread and the gRPC server
//! (with health, optional token authentication and the services the caller adds), writes metrics, and on SIGINT or
//! SIGTERM stops cleanly with a final checkpoint.
//!
//! A fresh run writes a checkpoint before it serves, so that `--resume` always finds one. With
//! `service.durability = "ack"`, resuming reads the replay log back into the replay and counts the
//! batches logged after the checkpoint. If the training thread dies (a panic) or the replay log
//! fails, the learner reports it (log, Status, health NOT_SERVING), acknowledges nothing more,
//! and `learner serve` exits non-zero: a supervisor restarts it with `--resume`.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::{Context, Result, bail};

use crate::service::tls::ServerTls;
use crate::shared_state::{PublishedWeights, Shared, SharedStart};
use crate::storage::checkpoint;
use crate::storage::replay::{Replay, ReplayConfig};
use crate::storage::replay_log::OnDamage;
use crate::storage::run_lock::RunLock;
use crate::storage::run_map::RunMap;
use crate::storage::versions::VersionLease;
use crate::telemetry::metrics_log::MetricsLog;
use crate::training::dqn::Dqn;
use agent::checkpoint::Counters;
use agent::config::Durability;
use endpoints::GrpcServer;
use run_dir::OpenedRun;

mod endpoints;
mod rebuild;
mod run_dir;
mod supervise;

pub use endpoints::resolve;
pub use run_dir::{ADDR_FILE, METRICS_ADDR_FILE};
pub use supervise::progress_loop;

/// Options of `learner serve`.
#[derive(Debug, Clone, Default)]
pub struct ServeOptions {
    pub config: Option<PathBuf>,
    pub listen: Option<String>,
    pub run_dir: Option<PathBuf>,
    pub resume: bool,
    /// Resume from the intact part of a damaged replay log (see [`OnDamage::Truncate`]).
    pub truncate_log: bool,
    pub metrics_listen: Option<String>,
    pub auth_token_file: Option<PathBuf>,
    /// TLS: override `service.tls_cert`, `service.tls_key`, `service.tls_client_ca`.
    pub tls_cert: Option<PathBuf>,
    pub tls_key: Option<PathBuf>,
    pub tls_client_ca: Option<PathBuf>,
    /// Services served beside the learner, on its listener and behind its TLS: the `learner`
    /// program adds server reflection here (`learner_cli::reflection`), so that the library, and
    /// the actor that runs it in process for `actor train`, link no reflection.
    pub extra_services: Option<tonic::service::Routes>,
}

/// Runs the service until SIGINT or SIGTERM, then stops it cleanly.
pub async fn serve(opts: ServeOptions) -> Result<()> {
    let running = start(opts).await?;
    let scheme = if running.tls.is_some() { "https" } else { "http" };
    eprintln!("learner listening on {scheme}://{} (run {} in {})", running.addr, running.shared.run_id, running.run_dir.display());
    eprintln!("status, from another terminal: learner status --run-dir {}", running.run_dir.display());
    let reporter = Arc::new(crate::telemetry::progress::Reporter::stderr());
    let progress = tokio::spawn(progress_loop(running.shared.clone(), reporter.clone(), Duration::from_secs(10)));
    tokio::select! {
        () = proto::shutdown::signal() => {}
        reason = running.failed() => {
            progress.abort();
            reporter.finish();
            let run_dir = running.run_dir.clone();
            // Let status queries see the reason for a moment, then go.
            tokio::time::sleep(Duration::from_secs(1)).await;
            let _ = running.stop().await;
            bail!(
                "the learner stopped: {reason}; acknowledged batches are in the replay log and the last checkpoint: \
                 restart with `learner serve --run-dir {} --resume`",
                run_dir.display()
            );
        }
    }
    progress.abort();
    reporter.finish();
    tracing::info!("stopping: finishing the current update and writing a checkpoint");
    let run_dir = running.run_dir.clone();
    let path = running.stop().await?;
    eprintln!("checkpoint written to {}; resume with: learner serve --run-dir {} --resume", path.display(), run_dir.display());
    Ok(())
}

/// A learner running in this process.
#[derive(Debug)]
pub struct Running {
    /// The bound gRPC address.
    pub addr: SocketAddr,
    pub run_dir: PathBuf,
    pub shared: Arc<Shared>,
    /// The server's TLS, when it serves TLS (reloaded on SIGHUP and when its files change).
    pub tls: Option<Arc<ServerTls>>,
    stop_server: tokio::sync::oneshot::Sender<()>,
    server: GrpcServer,
    trainer: std::thread::JoinHandle<Result<Dqn>>,
    /// This process owns the run directory until the learner is dropped.
    _lock: RunLock,
}

impl Running {
    /// Completes, with the reason, once the learner cannot go on (see [`Shared::fail`]).
    pub async fn failed(&self) -> Arc<str> {
        let mut rx = self.shared.failure.subscribe();
        let reason = rx.wait_for(Option::is_some).await.map(|f| f.clone()).ok().flatten();
        reason.unwrap_or_else(|| "the learner's state was dropped".into())
    }

    /// Stops serving, lets the training thread finish its update, writes the final checkpoint
    /// and flushes the metrics. Returns the checkpoint's path.
    pub async fn stop(self) -> Result<PathBuf> {
        self.shared.shutdown.store(true, Ordering::SeqCst);
        self.shared.backpressure.wake();
        let _ = self.stop_server.send(());
        // Graceful shutdown waits for open calls; actors' experience streams end at their next
        // batch (see `service.rs`), but do not wait on a silent one for ever.
        let mut server = self.server;
        match tokio::time::timeout(Duration::from_secs(3), &mut server).await {
            Ok(joined) => joined.context("joining the gRPC server")??,
            Err(_) => {
                tracing::warn!("open connections did not close within 3 s: closing them");
                server.abort();
            }
        }
        let (trainer, _lock) = (self.trainer, self._lock);
        let dqn =
            tokio::task::spawn_blocking(move || trainer.join()).await?.map_err(|_| anyhow::anyhow!("the training thread panicked"))??;
        if let Some(reason) = self.shared.failure() {
            bail!("the learner stopped: {reason}");
        }
        let path = crate::training::trainer::save_checkpoint(&self.shared, &dqn, &self.run_dir)?;
        self.shared.metrics.interval(&self.shared.train_record())?;
        Ok(path)
    }
}

/// Starts the service: loads or resumes the run, starts training and serving.
pub async fn start(opts: ServeOptions) -> Result<Running> {
    start_with(opts, crate::training::trainer::run).await
}

/// The training loop a learner runs (tests substitute one that fails).
pub(crate) type Trainer = fn(&Arc<Shared>, Dqn, &Path) -> Result<Dqn>;

pub(crate) async fn start_with(opts: ServeOptions, train: Trainer) -> Result<Running> {
    let OpenedRun { cfg, run_dir, lock } = run_dir::open(&opts)?;
    let map = RunMap::read(&cfg.env, cfg.service.max_message_bytes)?;
    if let Some(m) = &map {
        m.check_run_dir(&run_dir, opts.resume)?;
        tracing::info!(map = %m.name, bytes = m.text.len(), hash = %format!("{:016x}", m.hash), "the run's map, sent to every actor");
    }
    let token = opts.auth_token_file.as_deref().map(proto::client::read_token).transpose()?;
    let tls = endpoints::server_tls(&cfg.service)?;

    let shape = cfg.net_shape();
    let precision = cfg.agent.precision.resolve().context("[agent] precision")?;
    tracing::info!(bf16 = precision.bf16, "network arithmetic: {} ({})", precision.arithmetic(), precision.reason);
    let mut dqn = Dqn::new(shape, &cfg.agent);
    let mut counters = Counters::default();
    if opts.resume {
        let loaded = checkpoint::load(&run_dir, &mut dqn).with_context(|| format!("loading the checkpoint in {}", run_dir.display()))?;
        counters = loaded.counters;
        tracing::info!(learner_step = counters.learner_step, weights_version = counters.weights_version, "resumed");
    } else {
        counters.run_id = run_dir::new_run_id();
        // From the first moment, `--resume` finds a checkpoint (and the replay log beside it).
        checkpoint::save(&run_dir, &dqn, &counters, &cfg.to_toml())
            .with_context(|| format!("writing the first checkpoint in {}", run_dir.display()))?;
    }
    std::fs::write(run_dir.join("config.toml"), cfg.to_toml()).with_context(|| format!("writing {}/config.toml", run_dir.display()))?;

    let frame_bytes = cfg.frame_bytes();
    let a = &cfg.agent;
    let mut replay = Replay::new(ReplayConfig {
        capacity: a.replay_capacity,
        max_bytes: a.replay_max_bytes,
        frame_bytes,
        vector_len: cfg.vector_len(),
        channels: cfg.frame_channels(),
        stack: cfg.frame_stack(),
        gamma: a.gamma,
        n_step: a.n_step,
        prioritized: a.prioritized_replay,
        alpha: a.priority_alpha,
        beta: a.priority_beta,
        seed: a.seed ^ counters.learner_step,
    });
    if a.demo_capacity > 0 {
        // Its byte cap in proportion to its capacity, from the agent partition's.
        let max_bytes = (a.replay_max_bytes as f64 * a.demo_capacity as f64 / a.replay_capacity as f64) as u64;
        replay.keep_demonstrations(a.demo_capacity, max_bytes.max(1 << 20));
    }
    let log = match cfg.service.durability {
        Durability::None => None,
        Durability::Ack => {
            let on_damage = if opts.truncate_log { OnDamage::Truncate } else { OnDamage::Refuse };
            Some(rebuild::rebuild(&run_dir, &cfg, frame_bytes, on_damage, &mut replay, &mut counters)?)
        }
    };
    let mut versions = VersionLease::open(&run_dir, counters.weights_version)?;
    let version = versions.next_version().with_context(|| format!("leasing weights versions in {}", run_dir.display()))?;
    let weights = PublishedWeights { version, bytes: Arc::new(agent::weights::to_safetensors(&dqn.online, "")?) };
    counters.weights_version = weights.version;
    // The replay ratio counts what arrives from now on, before the training thread is first
    // scheduled: a burst that beats it there is held too.
    let ratio_session = Some((counters.transitions_stored, dqn.updates));
    let shared = Arc::new(Shared::new(SharedStart {
        cfg: cfg.clone(),
        map,
        replay,
        counters,
        weights,
        metrics: MetricsLog::open(&run_dir).with_context(|| format!("opening metrics files in {}", run_dir.display()))?,
        log,
        versions,
        ratio_session,
        resumed: opts.resume,
    }));

    // Training thread.
    let trainer = {
        let shared = shared.clone();
        let run_dir = run_dir.clone();
        std::thread::Builder::new().name("train".into()).spawn(move || supervise::supervised_training(&shared, dqn, &run_dir, train))?
    };

    // Metrics: rates, train.jsonl, Prometheus.
    tokio::spawn(supervise::report_loop(shared.clone()));
    if let Some(m) = &opts.metrics_listen {
        endpoints::serve_metrics(m, &run_dir, tls.as_ref(), &shared).await?;
    }
    let (bound, stop_server, server) =
        endpoints::serve_grpc(&cfg, &run_dir, tls.as_ref(), token, &shared, opts.extra_services.clone()).await?;
    Ok(Running { addr: bound, run_dir, shared, tls, stop_server, server, trainer, _lock: lock })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::v1 as pb;

    /// Training that dies (here a panic, as an assertion deep in an update would) does not stop
    /// silently while data flows in: Status names it, health turns NOT_SERVING, batches are
    /// refused with UNAVAILABLE, and stopping reports the failure (so `learner serve` exits
    /// non-zero).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_dead_training_thread_turns_the_learner_not_serving() {
        let dir = tempfile::tempdir().unwrap();
        let cfg_path = dir.path().join("run.toml");
        std::fs::write(&cfg_path, agent::config::RunConfig::tiny(&dir.path().join("run")).to_toml()).unwrap();
        let running = start_with(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }, |_, _, _| {
            std::thread::sleep(Duration::from_millis(300));
            panic!("injected: an update hit a bug")
        })
        .await
        .unwrap();
        let reason = running.failed().await;
        assert_eq!(&*reason, "the training thread panicked: injected: an update hit a bug");
        let addr = format!("http://{}", running.addr);
        let mut c = proto::v1::learner_client::LearnerClient::connect(addr.clone()).await.unwrap();
        let st = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
        assert_eq!(st.training_error, *reason);
        // Health: both the server and the learner service report NOT_SERVING (the reporter's
        // task runs beside this one: poll briefly).
        let channel = tonic::transport::Endpoint::from_shared(addr).unwrap().connect().await.unwrap();
        let mut health = tonic_health::pb::health_client::HealthClient::new(channel);
        for service in ["", "hybriddrive.v1.Learner"] {
            let mut status = 0;
            for _ in 0..100 {
                let req = tonic_health::pb::HealthCheckRequest { service: service.into() };
                status = health.check(req).await.unwrap().into_inner().status;
                if status == tonic_health::pb::health_check_response::ServingStatus::NotServing as i32 {
                    break;
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            assert_eq!(status, tonic_health::pb::health_check_response::ServingStatus::NotServing as i32, "service {service:?}");
        }
        // Data is refused, loudly.
        let reg =
            c.register(pb::RegisterRequest { name: "a".into(), envs: 1, protocol: 1, ..Default::default() }).await.unwrap().into_inner();
        let step = pb::Step { obs: Some(pb::Observation { image: vec![0; 256], ..Default::default() }), ..Default::default() };
        let batch = pb::ExperienceBatch { actor_id: reg.actor_id, seq: 1, steps: vec![step], ..Default::default() };
        let mut acks = c.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
        let refused = acks.message().await.unwrap_err();
        assert_eq!(refused.code(), tonic::Code::Unavailable);
        assert!(refused.message().contains("has stopped training (the training thread panicked"), "{}", refused.message());
        let e = running.stop().await.unwrap_err().to_string();
        assert!(e.contains("injected"), "{e}");
    }

    /// A burst that fills the replay before the training thread first runs is held as well: the
    /// replay ratio's count starts when the server does, not when the thread is scheduled (a
    /// loaded CI machine once let a whole burst through, 197 updates owed against a limit of 4).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_burst_before_the_training_thread_runs_is_held() {
        let dir = tempfile::tempdir().unwrap();
        let mut cfg = agent::config::RunConfig::tiny(&dir.path().join("run"));
        (cfg.agent.replay_ratio, cfg.agent.batch_size, cfg.agent.replay_capacity, cfg.agent.min_replay) = (8.0, 32, 5000, 100);
        cfg.service.update_lag_limit = 4;
        let cfg_path = dir.path().join("run.toml");
        std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
        // The thread sleeps through the burst, as a starved one would, then trains.
        let late = |shared: &Arc<Shared>, dqn, run_dir: &std::path::Path| {
            std::thread::sleep(Duration::from_millis(1500));
            crate::training::trainer::run(shared, dqn, run_dir)
        };
        let running = start_with(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }, late).await.unwrap();
        let mut c = proto::v1::learner_client::LearnerClient::connect(format!("http://{}", running.addr)).await.unwrap();
        let reg =
            c.register(pb::RegisterRequest { name: "a".into(), envs: 1, protocol: 1, ..Default::default() }).await.unwrap().into_inner();
        // Eight episodes of 100 steps (99 transitions each), one per batch, on one stream.
        let batches: Vec<_> = (0..8u64)
            .map(|e| {
                let steps = (0..100u32)
                    .map(|t| pb::Step {
                        episode: e,
                        t,
                        obs: Some(pb::Observation { image: vec![(t % 256) as u8; 256], d: 1.0, ..Default::default() }),
                        action: t % 6,
                        reward: 0.1,
                        ..Default::default()
                    })
                    .collect();
                pb::ExperienceBatch { actor_id: reg.actor_id.clone(), seq: e + 1, steps, weights_version: 1, ..Default::default() }
            })
            .collect();
        let mut acks = c.stream_experience(tokio_stream::iter(batches)).await.unwrap().into_inner();
        for _ in 0..8 {
            acks.message().await.unwrap().expect("an ack per batch");
        }
        let st = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
        let owed = (st.transitions_stored * 8 / 32).saturating_sub(st.learner_step);
        running.stop().await.unwrap();
        assert_eq!(st.transitions_stored, 8 * 99);
        // At most the limit, plus the 24.75 updates of the last batch stored, plus one of rounding.
        assert!(owed <= 4 + 25 + 1 && st.held_secs > 0.0, "{owed} updates owed, streams held {} s", st.held_secs);
    }
}
