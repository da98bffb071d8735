//! `learner serve`: loads or resumes a run, starts the training thread and the gRPC server
//! (with health, reflection, optional token authentication), writes metrics, and on SIGINT or
//! SIGTERM stops cleanly with a final checkpoint.
//!
//! A fresh run writes a checkpoint before it serves, so that `--resume` always finds one. With
//! `service.durability = "ack"`, resuming reads the replay log back into the replay and counts the
//! batches logged after the checkpoint. If the training thread dies (a panic) or the replay log
//! fails, the learner reports it (log, Status, health NOT_SERVING), acknowledges nothing more,
//! and `learner serve` exits non-zero: a supervisor restarts it with `--resume`.

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
use crate::run_lock::RunLock;
use crate::run_map::RunMap;
use crate::service::LearnerService;
use crate::state::{PublishedWeights, Shared, TrainStats};
use crate::tls::{Alpn, ServerTls, ServerTlsFiles};
use crate::versions::VersionLease;
use crate::wal::{OnDamage, ReplayLog};
use agent::checkpoint::Counters;
use agent::config::{Durability, RunConfig};

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
}

/// Resolves `host:port` or `http://host:port` to a socket address; a bare port is loopback's.
pub async fn resolve(addr: &str) -> Result<SocketAddr> {
    if let Ok(port) = addr.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
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
    let scheme = if running.tls.is_some() { "https" } else { "http" };
    eprintln!("learner listening on {scheme}://{} (run {} in {})", running.addr, running.shared.run_id, running.run_dir.display());
    eprintln!("status, from another terminal: learner status --run-dir {}", running.run_dir.display());
    let reporter = Arc::new(crate::progress::Reporter::stderr());
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
    server: tokio::task::JoinHandle<Result<(), tonic::transport::Error>>,
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
        let path = crate::train::save_checkpoint(&self.shared, &dqn, &self.run_dir)?;
        self.shared.metrics.interval(&self.shared.train_record())?;
        Ok(path)
    }
}

/// Starts the service: loads or resumes the run, starts training and serving.
pub async fn start(opts: ServeOptions) -> Result<Running> {
    start_with(opts, crate::train::run).await
}

/// The training loop a learner runs (tests substitute one that fails).
type Trainer = fn(&Arc<Shared>, Dqn, &Path) -> Result<Dqn>;

async fn start_with(opts: ServeOptions, train: Trainer) -> Result<Running> {
    let mut cfg = match &opts.config {
        Some(p) => RunConfig::load(p)?,
        None => RunConfig::default(),
    };
    if let Some(dir) = &opts.run_dir {
        cfg.service.run_dir = dir.display().to_string();
    }
    let run_dir = PathBuf::from(&cfg.service.run_dir);
    std::fs::create_dir_all(&run_dir).with_context(|| format!("creating run directory {}", run_dir.display()))?;
    // Before anything is read: a second process on this run would corrupt it.
    let lock = RunLock::acquire(&run_dir)?;
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
    for (flag, field) in [
        (&opts.tls_cert, &mut cfg.service.tls_cert),
        (&opts.tls_key, &mut cfg.service.tls_key),
        (&opts.tls_client_ca, &mut cfg.service.tls_client_ca),
    ] {
        if let Some(path) = flag {
            *field = path.display().to_string();
        }
    }
    cfg.validate().map_err(|(field, message)| anyhow::anyhow!("config field `{field}`: {message}"))?;
    let map = RunMap::read(&cfg.env, cfg.service.max_message_bytes)?;
    if let Some(m) = &map {
        m.check_run_dir(&run_dir, opts.resume)?;
        tracing::info!(map = %m.name, bytes = m.text.len(), hash = %format!("{:016x}", m.hash), "the run's map, sent to every actor");
    }
    let token = opts.auth_token_file.as_deref().map(proto::client::read_token).transpose()?;
    let tls = server_tls(&cfg.service)?;

    let shape = cfg.net_shape();
    let precision = cfg.agent.precision.resolve().context("[agent] precision")?;
    tracing::info!(
        bf16 = precision.bf16,
        "network arithmetic: {} ({})",
        if precision.bf16 { "bf16 on AMX" } else { "f32" },
        precision.reason
    );
    let mut dqn = Dqn::new(shape, &cfg.agent);
    let mut counters = Counters::default();
    if opts.resume {
        let loaded = checkpoint::load(&run_dir, &mut dqn).with_context(|| format!("loading the checkpoint in {}", run_dir.display()))?;
        counters = loaded.counters;
        tracing::info!(learner_step = counters.learner_step, weights_version = counters.weights_version, "resumed");
    } else {
        counters.run_id = new_run_id();
        // From the first moment, `--resume` finds a checkpoint (and the replay log beside it).
        checkpoint::save(&run_dir, &dqn, &counters, &cfg.to_toml())
            .with_context(|| format!("writing the first checkpoint in {}", run_dir.display()))?;
    }
    std::fs::write(run_dir.join("config.toml"), cfg.to_toml()).with_context(|| format!("writing {}/config.toml", run_dir.display()))?;

    let frame_bytes = shape.height * shape.width * shape.channels;
    let a = &cfg.agent;
    let mut replay = Replay::new(ReplayConfig {
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
    let log = match cfg.service.durability {
        Durability::None => None,
        Durability::Ack => {
            let on_damage = if opts.truncate_log { OnDamage::Truncate } else { OnDamage::Refuse };
            Some(rebuild(&run_dir, &cfg, frame_bytes, on_damage, &mut replay, &mut counters)?)
        }
    };
    let mut versions = VersionLease::open(&run_dir, counters.weights_version)?;
    let version = versions.next_version().with_context(|| format!("leasing weights versions in {}", run_dir.display()))?;
    let weights = PublishedWeights { version, bytes: Arc::new(agent::weights::to_safetensors(&dqn.online, "")?) };
    counters.weights_version = weights.version;
    let elapsed_before = counters.elapsed_secs;
    let shared = Arc::new(Shared {
        run_id: counters.run_id.clone(),
        cfg: cfg.clone(),
        map,
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
        resumed: opts.resume,
        log,
        versions: Mutex::new(versions),
        registrations: Default::default(),
        refused: Default::default(),
        warned_peers: Default::default(),
        failure: tokio::sync::watch::Sender::new(None),
        checkpoint_error: Mutex::new(None),
        last_refusal: Mutex::new(None),
    });

    // Training thread.
    let trainer = {
        let shared = shared.clone();
        let run_dir = run_dir.clone();
        std::thread::Builder::new().name("train".into()).spawn(move || supervised_training(&shared, dqn, &run_dir, train))?
    };

    // Metrics: rates, train.jsonl, Prometheus.
    tokio::spawn(report_loop(shared.clone()));
    if let Some(m) = &opts.metrics_listen {
        let addr = resolve(m).await?;
        let listener = tokio::net::TcpListener::bind(addr).await.with_context(|| format!("binding metrics address {addr}"))?;
        let local = listener.local_addr()?;
        std::fs::write(run_dir.join("metrics.addr"), local.to_string())?;
        warn_if_in_clear("the metrics endpoint (--metrics-listen)", local, tls.is_some());
        match &tls {
            Some(t) => {
                tracing::info!(addr = %local, "Prometheus metrics at https://{local}/metrics");
                let connections = crate::tls::accept_tls(listener, t.clone(), Alpn::Http1);
                tokio::spawn(serve_prometheus(crate::tls::TlsListener { connections, local }, shared.clone()));
            }
            None => {
                tracing::info!(addr = %local, "Prometheus metrics at http://{local}/metrics");
                tokio::spawn(serve_prometheus(listener, shared.clone()));
            }
        }
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
    {
        // A learner that cannot go on says so to health checks (the whole server and the
        // learner service), so that orchestrators restart it.
        let shared = shared.clone();
        let reporter = health_reporter.clone();
        tokio::spawn(async move {
            let mut rx = shared.failure.subscribe();
            if rx.wait_for(Option::is_some).await.is_ok() {
                reporter.set_not_serving::<LearnerServer<LearnerService>>().await;
                reporter.set_service_status("", tonic_health::ServingStatus::NotServing).await;
            }
        });
    }
    tracing::info!(addr = %bound, tls = tls.is_some(), mutual_tls = tls.as_ref().is_some_and(|t| t.mutual()), run_dir = %run_dir.display(), run_id = %shared.run_id, "learner listening");
    warn_if_in_clear("the gRPC service (--listen)", bound, tls.is_some());
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
    let stopped = async move {
        let _ = stopped.await;
    };
    // Health and reflection share the listener, and so its TLS.
    let server = match &tls {
        Some(t) => {
            use tokio_stream::StreamExt;
            tokio::spawn(crate::tls::watch_and_reload(t.clone()));
            let connections = crate::tls::accept_tls(listener, t.clone(), Alpn::Grpc);
            let incoming = tokio_stream::wrappers::ReceiverStream::new(connections).map(|(stream, _)| Ok::<_, std::io::Error>(stream));
            tokio::spawn(router.serve_with_incoming_shutdown(incoming, stopped))
        }
        None => tokio::spawn(router.serve_with_incoming_shutdown(tokio_stream::wrappers::TcpListenerStream::new(listener), stopped)),
    };
    Ok(Running { addr: bound, run_dir, shared, tls, stop_server, server, trainer, _lock: lock })
}

/// The server's TLS from `[service]` (after the flags), or `None` for plaintext.
fn server_tls(s: &agent::config::ServiceConfig) -> Result<Option<Arc<ServerTls>>> {
    if s.tls_cert.is_empty() {
        return Ok(None);
    }
    let files = ServerTlsFiles {
        cert: s.tls_cert.clone().into(),
        key: s.tls_key.clone().into(),
        client_ca: (!s.tls_client_ca.is_empty()).then(|| s.tls_client_ca.clone().into()),
    };
    Ok(Some(ServerTls::load(files)?))
}

/// One WARN when `what` listens beyond loopback in clear.
fn warn_if_in_clear(what: &str, addr: SocketAddr, tls: bool) {
    if !tls && !addr.ip().is_loopback() {
        tracing::warn!(
            %addr,
            "{what} listens on a non-loopback address without TLS: tokens, experience and weights cross the network in clear; \
             serve TLS with --tls-cert FILE --tls-key FILE (and --tls-client-ca FILE for mutual TLS; `learner certs` makes them)"
        );
    }
}

/// Runs training, turning its end other than by a requested stop (an error or a panic) into a
/// failure of the learner.
fn supervised_training(shared: &Arc<Shared>, dqn: Dqn, run_dir: &Path, train: Trainer) -> Result<Dqn> {
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| train(shared, dqn, run_dir)));
    let reason = match outcome {
        Ok(Ok(dqn)) if shared.stopping() => return Ok(dqn),
        Ok(Ok(_)) => "the training thread returned unexpectedly".to_owned(),
        Ok(Err(e)) => format!("training failed: {e:#}"),
        Err(panic) => {
            let what = panic.downcast_ref::<String>().cloned().or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()));
            format!("the training thread panicked: {}", what.unwrap_or_else(|| "(no message)".into()))
        }
    };
    shared.fail(reason.clone());
    bail!(reason)
}

/// Opens the replay log of `run_dir`, rebuilding `replay` from it, and adds the batches logged
/// after the checkpoint (`counters.replay_log_position`) to `counters`.
fn rebuild(
    run_dir: &Path,
    cfg: &RunConfig,
    frame_bytes: usize,
    on_damage: OnDamage,
    replay: &mut Replay,
    counters: &mut Counters,
) -> Result<ReplayLog> {
    let started = Instant::now();
    let checkpointed = counters.replay_log_position;
    let mut after = Counters::default();
    let (log, found) =
        ReplayLog::open(run_dir, frame_bytes, cfg.service.replay_log_segment_bytes, checkpointed, on_damage, |position, record| {
            let stored = replay.add_steps(record.actor, &record.steps) as u64;
            if position > checkpointed {
                let env_steps = record.steps.iter().filter(|s| s.t > 0).count() as u64;
                after.env_steps += env_steps;
                after.transitions_received += env_steps;
                after.transitions_stored += stored;
                after.episodes += u64::from(record.episodes);
                after.replay_log_position = position;
            }
            replay.next_frame_id()
        })?;
    // No actor continues an earlier process's streams.
    replay.end_all_streams();
    counters.env_steps += after.env_steps;
    counters.transitions_received += after.transitions_received;
    counters.transitions_stored += after.transitions_stored;
    counters.episodes += after.episodes;
    counters.replay_log_position = counters.replay_log_position.max(after.replay_log_position).max(found.last_position);
    log.note_frames(replay.next_frame_id(), replay.first_frame_id());
    if found.records > 0 {
        tracing::info!(
            batches = found.records,
            segments = found.segments,
            replay_size = replay.len(),
            batches_after_checkpoint = found.last_position.saturating_sub(checkpointed),
            secs = format!("{:.1}", started.elapsed().as_secs_f64()),
            "replay rebuilt from the replay log"
        );
    }
    Ok(log)
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
        std::fs::write(&cfg_path, RunConfig::tiny(&dir.path().join("run")).to_toml()).unwrap();
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
        let reg = c.register(pb::RegisterRequest { name: "a".into(), envs: 1, protocol: 1 }).await.unwrap().into_inner();
        let step = pb::Step { obs: Some(pb::Observation { image: vec![0; 256], ..Default::default() }), ..Default::default() };
        let batch = pb::ExperienceBatch { actor_id: reg.actor_id, seq: 1, steps: vec![step], ..Default::default() };
        let mut acks = c.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
        let refused = acks.message().await.unwrap_err();
        assert_eq!(refused.code(), tonic::Code::Unavailable);
        assert!(refused.message().contains("has stopped training (the training thread panicked"), "{}", refused.message());
        let e = running.stop().await.unwrap_err().to_string();
        assert!(e.contains("injected"), "{e}");
    }
}
