//! `learner serve`: loads or resumes a run, starts the training thread and the gRPC server
//! (with health, reflection, optional token authentication), writes metrics, and on SIGINT or
//! SIGTERM stops cleanly with a final checkpoint.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex, RwLock};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use proto::v1::learner_server::LearnerServer;
use tonic::codec::CompressionEncoding;

use crate::checkpoint;
use crate::dqn::Dqn;
use crate::metrics_log::MetricsLog;
use crate::progress::RateMeter;
use crate::prometheus::serve_prometheus;
use crate::replay::{Replay, ReplayConfig};
use crate::service::LearnerService;
use crate::state::{PublishedWeights, Shared, TrainStats};
use agent::checkpoint::Counters;
use agent::config::RunConfig;

/// Options of `learner serve`.
#[derive(Debug, Clone, Default)]
pub struct ServeOptions {
    pub config: Option<PathBuf>,
    pub listen: Option<String>,
    pub run_dir: Option<PathBuf>,
    pub resume: bool,
    pub metrics_listen: Option<String>,
    pub auth_token_file: Option<PathBuf>,
}

/// Resolves `host:port` or `http://host:port` to a socket address.
pub async fn resolve(addr: &str) -> Result<SocketAddr> {
    let bare = addr.trim_start_matches("http://").trim_start_matches("https://").trim_end_matches('/');
    tokio::net::lookup_host(bare)
        .await
        .with_context(|| format!("resolving address `{addr}` (expected host:port, e.g. 127.0.0.1:50051)"))?
        .next()
        .with_context(|| format!("address `{addr}` resolved to nothing"))
}

/// Runs the service until SIGINT or SIGTERM, then stops it cleanly.
pub async fn serve(opts: ServeOptions) -> Result<()> {
    let running = start(opts).await?;
    eprintln!("learner listening on {} (run {} in {})", running.addr, running.shared.run_id, running.run_dir.display());
    eprintln!("status, from another terminal: learner status --run-dir {}", running.run_dir.display());
    let reporter = Arc::new(crate::progress::Reporter::stderr());
    let progress = tokio::spawn(progress_loop(running.shared.clone(), reporter.clone(), Duration::from_secs(10)));
    proto::shutdown::signal().await;
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
    stop_server: tokio::sync::oneshot::Sender<()>,
    server: tokio::task::JoinHandle<Result<(), tonic::transport::Error>>,
    trainer: std::thread::JoinHandle<Result<Dqn>>,
}

impl Running {
    /// Stops serving, lets the training thread finish its update, writes the final checkpoint
    /// and flushes the metrics. Returns the checkpoint's path.
    pub async fn stop(self) -> Result<PathBuf> {
        self.shared.shutdown.store(true, Ordering::SeqCst);
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
        let trainer = self.trainer;
        let dqn =
            tokio::task::spawn_blocking(move || trainer.join()).await?.map_err(|_| anyhow::anyhow!("the training thread panicked"))??;
        let path = crate::train::save_checkpoint(&self.shared, &dqn, &self.run_dir)?;
        self.shared.metrics.interval(&self.shared.train_record())?;
        Ok(path)
    }
}

/// Starts the service: loads or resumes the run, starts training and serving.
pub async fn start(opts: ServeOptions) -> Result<Running> {
    let mut cfg = match &opts.config {
        Some(p) => RunConfig::load(p)?,
        None => RunConfig::default(),
    };
    if let Some(dir) = &opts.run_dir {
        cfg.service.run_dir = dir.display().to_string();
    }
    let run_dir = PathBuf::from(&cfg.service.run_dir);
    std::fs::create_dir_all(&run_dir).with_context(|| format!("creating run directory {}", run_dir.display()))?;
    if opts.resume {
        let text = checkpoint_config_text(&run_dir)?;
        let from_ckpt = RunConfig::from_toml(&text, &format!("{}/checkpoint/config.toml", run_dir.display()))?;
        if opts.config.is_some() && from_ckpt.env != cfg.env {
            bail!(
                "--config describes another environment than the checkpoint in {}: resume without --config, or start a new run directory",
                run_dir.display()
            );
        }
        let service = cfg.service.clone();
        cfg = from_ckpt;
        cfg.service = service;
    } else if checkpoint::exists(&run_dir) {
        bail!("run directory {} already holds a checkpoint: pass --resume to continue it, or choose another --run-dir", run_dir.display());
    }
    if let Some(l) = &opts.listen {
        cfg.service.listen = l.clone();
    }
    cfg.validate().map_err(|(field, message)| anyhow::anyhow!("config field `{field}`: {message}"))?;
    let token = opts.auth_token_file.as_deref().map(proto::client::read_token).transpose()?;

    let shape = cfg.net_shape();
    let mut dqn = Dqn::new(shape, &cfg.agent);
    let mut counters = Counters::default();
    if opts.resume {
        let loaded = checkpoint::load(&run_dir, &mut dqn).with_context(|| format!("loading the checkpoint in {}", run_dir.display()))?;
        counters = loaded.counters;
        tracing::info!(learner_step = counters.learner_step, weights_version = counters.weights_version, "resumed");
    } else {
        counters.run_id = new_run_id();
    }
    std::fs::write(run_dir.join("config.toml"), cfg.to_toml()).with_context(|| format!("writing {}/config.toml", run_dir.display()))?;

    let frame_bytes = shape.height * shape.width * shape.channels;
    let a = &cfg.agent;
    let replay = Replay::new(ReplayConfig {
        capacity: a.replay_capacity,
        max_bytes: a.replay_max_bytes,
        frame_bytes,
        gamma: a.gamma,
        n_step: a.n_step,
        prioritized: a.prioritized_replay,
        alpha: a.priority_alpha,
        beta: a.priority_beta,
        seed: a.seed ^ counters.learner_step,
    });
    let weights =
        PublishedWeights { version: counters.weights_version.max(1), bytes: Arc::new(agent::weights::to_safetensors(&dqn.online, "")?) };
    counters.weights_version = weights.version;
    let elapsed_before = counters.elapsed_secs;
    let shared = Arc::new(Shared {
        run_id: counters.run_id.clone(),
        cfg: cfg.clone(),
        started: Instant::now(),
        shape,
        frame_bytes,
        replay: Mutex::new(replay),
        counters: Mutex::new(counters),
        weights: RwLock::new(weights),
        actors: Mutex::new(Vec::new()),
        recent_episodes: Mutex::new(VecDeque::new()),
        stats: Mutex::new(TrainStats::default()),
        metrics: MetricsLog::open(&run_dir).with_context(|| format!("opening metrics files in {}", run_dir.display()))?,
        data_arrived: (Mutex::new(()), Condvar::new()),
        shutdown: Default::default(),
        elapsed_before,
    });

    // Training thread.
    let trainer = {
        let shared = shared.clone();
        let run_dir = run_dir.clone();
        std::thread::Builder::new().name("train".into()).spawn(move || crate::train::run(&shared, dqn, &run_dir))?
    };

    // Metrics: rates, train.jsonl, Prometheus.
    tokio::spawn(report_loop(shared.clone()));
    if let Some(m) = &opts.metrics_listen {
        let addr = resolve(m).await?;
        let listener = tokio::net::TcpListener::bind(addr).await.with_context(|| format!("binding metrics address {addr}"))?;
        std::fs::write(run_dir.join("metrics.addr"), listener.local_addr()?.to_string())?;
        tracing::info!(addr = %listener.local_addr()?, "Prometheus metrics at http://{}/metrics", listener.local_addr()?);
        tokio::spawn(serve_prometheus(listener, shared.clone()));
    }

    // gRPC.
    let addr = resolve(&cfg.service.listen).await?;
    let listener =
        tokio::net::TcpListener::bind(addr).await.with_context(|| format!("binding gRPC address {addr} (service.listen / --listen)"))?;
    let bound = listener.local_addr()?;
    std::fs::write(run_dir.join(crate::status::ADDR_FILE), bound.to_string())?;
    let max = cfg.service.max_message_bytes;
    let server = LearnerServer::new(LearnerService { shared: shared.clone() })
        .max_decoding_message_size(max)
        .max_encoding_message_size(max)
        .accept_compressed(CompressionEncoding::Zstd)
        .send_compressed(CompressionEncoding::Zstd);
    let svc = tonic::service::interceptor::InterceptedService::new(server, crate::auth::interceptor(token));
    let (health_reporter, health) = tonic_health::server::health_reporter();
    health_reporter.set_serving::<LearnerServer<LearnerService>>().await;
    tracing::info!(addr = %bound, run_dir = %run_dir.display(), run_id = %shared.run_id, "learner listening");
    let incoming = tokio_stream::wrappers::TcpListenerStream::new(listener);
    let (stop_server, stopped) = tokio::sync::oneshot::channel::<()>();
    // Batches of frames are large: HTTP/2's default 64 KiB flow-control window would stall each
    // one on window updates.
    let router = tonic::transport::Server::builder()
        .initial_stream_window_size(Some(proto::client::STREAM_WINDOW))
        .initial_connection_window_size(Some(proto::client::CONNECTION_WINDOW))
        // Streams of actors that vanished without closing (a cut network) end within ~30 s.
        .http2_keepalive_interval(Some(std::time::Duration::from_secs(10)))
        .http2_keepalive_timeout(Some(std::time::Duration::from_secs(20)))
        .add_service(health)
        .add_service(svc);
    // Server reflection in both protocol revisions: `grpc.reflection.v1` (grpcurl, current
    // clients) and `grpc.reflection.v1alpha`, which many stock clients still speak only (grpcio's
    // Python `ProtoReflectionDescriptorDatabase`, older grpcurl builds, GUI clients).
    #[cfg(feature = "reflection")]
    let router = {
        let reflection = || {
            tonic_reflection::server::Builder::configure()
                .register_encoded_file_descriptor_set(proto::v1::FILE_DESCRIPTOR_SET)
                .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        };
        router.add_service(reflection().build_v1()?).add_service(reflection().build_v1alpha()?)
    };
    let server = tokio::spawn(router.serve_with_incoming_shutdown(incoming, async move {
        let _ = stopped.await;
    }));
    Ok(Running { addr: bound, run_dir, shared, stop_server, server, trainer })
}

/// The configuration saved with the checkpoint of `run_dir` (verified again, with everything else,
/// when the checkpoint is loaded).
fn checkpoint_config_text(run_dir: &Path) -> Result<String> {
    for dir in [agent::checkpoint::DIR, agent::checkpoint::OLD_DIR] {
        let p = run_dir.join(dir).join(agent::checkpoint::CONFIG);
        if p.exists() {
            return std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()));
        }
    }
    bail!("--resume: run directory {} holds no checkpoint (expected {}/checkpoint/)", run_dir.display(), run_dir.display())
}

/// A run id: time-based, unique enough to tell runs apart.
fn new_run_id() -> String {
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    format!("run-{}-{:04x}", t.as_secs(), (t.subsec_nanos() >> 8) & 0xffff)
}

/// Every second: this session's rates (over the last 10 s of counters); every 10 s: a
/// train.jsonl line.
async fn report_loop(shared: Arc<Shared>) {
    let counters = || {
        let c = shared.counters.lock().expect("counters lock");
        (c.learner_step, c.env_steps)
    };
    let session = Instant::now();
    let (mut update_rate, mut step_rate) = (RateMeter::new(10.0), RateMeter::new(10.0));
    let (updates, steps) = counters();
    update_rate.push(0.0, updates);
    step_rate.push(0.0, steps);
    let mut tick = 0u64;
    loop {
        tokio::time::sleep(Duration::from_secs(1)).await;
        if shared.stopping() {
            return;
        }
        let (updates, steps) = counters();
        let t = session.elapsed().as_secs_f64();
        update_rate.push(t, updates);
        step_rate.push(t, steps);
        {
            let mut s = shared.stats.lock().expect("stats lock");
            s.updates_per_sec = update_rate.rate();
            s.env_steps_per_sec = step_rate.rate();
            s.epsilon = f64::from(shared.cfg.epsilon(0, steps));
        }
        tick += 1;
        if tick.is_multiple_of(10)
            && let Err(err) = shared.metrics.interval(&shared.train_record())
        {
            tracing::warn!(%err, "writing train.jsonl");
        }
    }
}

/// Shows the progress line (`crate::progress`) every `every` until aborted.
pub async fn progress_loop(shared: Arc<Shared>, reporter: Arc<crate::progress::Reporter>, every: Duration) {
    let session = Instant::now();
    loop {
        tokio::time::sleep(every).await;
        let status = crate::service::status(&shared);
        reporter.update(&crate::progress::line(session.elapsed().as_secs_f64(), &status));
    }
}
