//! `actor --learner ADDR`: one actor process. It registers with the learner (retrying with
//! exponential backoff and jitter), starts the stepping thread (`stepper.rs`: N environments,
//! one batched forward pass, ε-greedy) and streams its steps in batches. Steps go to a bounded
//! outbox (`outbox.rs`) that a sender task drains, new weights are picked up between steps, and a
//! lost or frozen learner only means buffering, counting what overflowed, and reconnecting; the
//! one wait is for a learner that is there and taking batches but behind the replay ratio
//! (`Link::wait_for_room`). SIGINT/SIGTERM: stop stepping, flush what can be sent within
//! [`FLUSH_DEADLINE`] (even to a frozen learner), say how many steps could not be sent, exit 0.
//!
//! Batches are cut below the learner's `max_message_bytes` and `max_batch_steps` (`batch_split.rs`). A
//! refusal is logged with the learner's reason (ERROR for a batch it will never take, which is
//! dropped and counted; WARN otherwise), and every failed stream is followed by a wait that grows
//! from 0.5 s to 30 s (±25 %) until a batch is acknowledged again: never a tight reconnect loop.

pub mod batch_split;
pub mod demonstrator;
pub mod explore;
pub mod outbox;
pub mod stepper;
pub mod town;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use agent::NetShape;
use agent::backoff::Backoff;
use agent::config::{AgentConfig, RunConfig};
use anyhow::{Context, Result};
// `connect_to`: plaintext or TLS, as `opts.learner` says (and never a token in clear off loopback).
use proto::client::{ACTOR_ID_HEADER, Client, connect_to as connect};
use proto::v1 as pb;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::sampling::batch_split::{Limits, fits, split};
use crate::sampling::outbox::{Link, Outbox};
use crate::sampling::stepper::step_loop;

/// How long a stopping actor keeps trying to hand its buffered steps to the learner.
pub const FLUSH_DEADLINE: Duration = Duration::from_secs(5);

/// Options of an actor process.
#[derive(Debug, Clone)]
pub struct ActorOptions {
    /// The learner: its address, plaintext or TLS (`--learner`, `--tls-ca`, ...).
    pub learner: proto::client::Target,
    pub envs: usize,
    pub name: String,
    pub auth_token_file: Option<PathBuf>,
    /// Steps per batch sent.
    pub batch_steps: usize,
    /// Steps the outbox keeps while the learner is away; older ones are dropped (and counted).
    pub buffer_steps: usize,
    pub seed: u64,
    /// Appends a JSON line per acknowledged batch to this file (for audits such as the chaos
    /// test: which batches the learner promised to keep, where in its replay log, and the ε they
    /// were taken with).
    pub ack_log: Option<PathBuf>,
    /// Exit when standard input closes (the parent that started this actor died).
    pub exit_with_stdin: bool,
    /// Drive with this demonstrator instead of the learner's weights, and send demonstrations
    /// (`--demonstrate`).
    pub demonstrate: Option<crate::sampling::demonstrator::Demonstrator>,
}

/// Registers, retrying with exponential backoff (0.5 s doubling to 30 s, ±25 % jitter) until it
/// succeeds or stop is requested.
async fn register(
    opts: &ActorOptions,
    token: &Option<String>,
    link: &Link,
    envs: usize,
    rng: &mut ChaCha8Rng,
) -> Option<(Client, pb::RegisterResponse)> {
    let mut backoff = retry_backoff();
    // Said at WARN at the first failure and then once a minute, with the attempts in between.
    let (mut warned, mut failures) = (None::<Instant>, 0u32);
    loop {
        if link.stop.load(Ordering::SeqCst) {
            return None;
        }
        let attempt = async {
            let mut client = connect(&opts.learner, token.clone()).await?;
            let reg = client
                .register(pb::RegisterRequest {
                    name: opts.name.clone(),
                    envs: envs as u32,
                    protocol: proto::v1::PROTOCOL,
                    vector_layout: sim_core::sensor::LAYOUT_VERSION.into(),
                    demonstrator: opts.demonstrate.map(|d| d.name().to_owned()).unwrap_or_default(),
                })
                .await
                .map_err(|s| anyhow::anyhow!("register: {}", s.message()))?
                .into_inner();
            anyhow::Ok((client, reg))
        };
        match attempt.await {
            Ok(ok) => return Some(ok),
            Err(err) => {
                let wait = backoff.next_wait_jittered(rng);
                failures += 1;
                let error = format!("{err:#}");
                if warned.is_none_or(|t| t.elapsed() >= Duration::from_secs(60)) {
                    tracing::warn!(learner = %opts.learner, %error, attempts = failures, retry_in_secs = format!("{:.1}", wait.as_secs_f64()), "learner unreachable (said once a minute while it lasts)");
                    warned = Some(Instant::now());
                } else {
                    tracing::debug!(learner = %opts.learner, %error, retry_in_secs = format!("{:.1}", wait.as_secs_f64()), "learner unreachable");
                }
                wait_to_retry(link, wait).await;
            }
        }
    }
}

async fn sleep_unless_stopped(link: &Link, d: Duration) {
    sleep_until(link, d, false).await;
}

/// A backoff wait before connecting again: ends early on stop, or when the weights poll finds the
/// learner back after it was unreachable (a restarted learner: register again now, not after a
/// backoff grown while it was down).
async fn wait_to_retry(link: &Link, d: Duration) {
    sleep_until(link, d, true).await;
}

/// Sleeps `d` in steps of 50 ms, ending early on stop or, with `until_learner_back`, when the
/// learner answers again (the notice is consumed).
async fn sleep_until(link: &Link, d: Duration, until_learner_back: bool) {
    let end = Instant::now() + d;
    while Instant::now() < end && !link.stop.load(Ordering::SeqCst) {
        if until_learner_back && link.learner_back.swap(false, Ordering::SeqCst) {
            tracing::info!("the learner answers again: connecting now");
            return;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Runs the actor until SIGINT/SIGTERM.
pub async fn run(opts: ActorOptions) -> Result<()> {
    if opts.envs == 0 || opts.envs > 1024 {
        anyhow::bail!("--envs {} must be 1..=1024", opts.envs);
    }
    let token = opts.auth_token_file.as_deref().map(proto::client::read_token).transpose()?;
    if token.is_some() {
        // Refused once, before any connection, rather than at every retry.
        opts.learner.check_token_safety().await?;
    }
    let link = Arc::new(Link::default());
    let mut ack_log = AckLog::open(opts.ack_log.as_deref())?;
    if opts.exit_with_stdin {
        exit_when_stdin_closes()?;
    }
    {
        let link = link.clone();
        tokio::spawn(async move {
            proto::shutdown::signal().await;
            tracing::info!("stopping: flushing buffered steps");
            link.stop.store(true, Ordering::SeqCst);
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ std::process::id() as u64);
    let Some((client, reg)) = register(&opts, &token, &link, opts.envs, &mut rng).await else { return Ok(()) };
    tracing::info!(
        actor_id = %reg.actor_id,
        index = reg.actor_index,
        run_id = %reg.run_id,
        envs = opts.envs,
        run_env_steps = reg.run_env_steps,
        episode_stream = reg.episode_stream,
        "registered"
    );
    link.note_run_env_steps(reg.run_env_steps);
    link.actor_id.lock().expect("actor id lock").clone_from(&reg.actor_id);
    let env_cfg = agent::config::env_from_toml(&reg.env_config_toml).context("the learner's [env] configuration")?;
    let agent_cfg: AgentConfig = toml::from_str(&reg.agent_config_toml).context("the learner's [agent] configuration")?;
    let run_cfg = RunConfig { env: env_cfg, agent: agent_cfg, ..RunConfig::default() };
    // Built once, before stepping: a map that does not arrive whole or does not build stops the
    // actor here, with the reason.
    let town = crate::sampling::town::run_town(&run_cfg.env, &reg)?;
    tracing::info!(town = %town.map.name, lanes = town.map.lanes.len(), map_file = %reg.map_name, map_hash = %format!("{:016x}", reg.map_hash), "driving the run's town");

    // The stepping thread: environments and inference.
    let stepper = {
        let link = link.clone();
        let cfg = run_cfg.clone();
        let (envs, seed, index, stream) = (opts.envs, opts.seed, reg.actor_index, reg.episode_stream);
        let (batch_steps, buffer_steps, demonstrate) = (opts.batch_steps, opts.buffer_steps, opts.demonstrate);
        std::thread::Builder::new().name("step".into()).spawn(move || {
            let r = step_loop(&cfg, &town, &link, envs, seed, index, stream, batch_steps, buffer_steps, demonstrate);
            link.stepper_done.store(true, Ordering::SeqCst);
            r
        })?
    };
    link.connected.store(true, Ordering::SeqCst);
    // A demonstrator drives without weights: it asks for none, and keeps pace with the run.
    let weights = if opts.demonstrate.is_some() {
        tokio::spawn(pace_loop(opts.clone(), token.clone(), link.clone(), client.clone()))
    } else {
        tokio::spawn(weights_loop(opts.clone(), token.clone(), link.clone(), client.clone(), run_cfg.net_shape()))
    };
    let progress = tokio::spawn(progress_loop(link.clone()));
    // Sending ends when stopped and flushed, or at the flush deadline, whatever the learner does
    // (a frozen learner holds a call open for ever).
    let flush_deadline = async {
        while !link.stop.load(Ordering::SeqCst) {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        tokio::time::sleep(FLUSH_DEADLINE).await;
    };
    tokio::select! {
        () = send_loop(&opts, &token, &link, client, reg, &mut rng, &mut ack_log) => {}
        () = flush_deadline => {}
    }
    weights.abort();
    progress.abort();
    let stepped =
        tokio::task::spawn_blocking(move || stepper.join()).await?.map_err(|_| anyhow::anyhow!("the stepping thread panicked"))?;
    stepped?;
    let ob = link.outbox.lock().expect("outbox lock");
    if ob.steps > 0 {
        tracing::warn!(
            unsent_steps = ob.steps,
            flush_deadline_secs = FLUSH_DEADLINE.as_secs(),
            "could not send {} steps to the learner before exiting (it did not acknowledge them within the flush deadline)",
            ob.steps
        );
    }
    tracing::info!(unsent_steps = ob.steps, dropped_steps = ob.dropped, env_steps = link.env_steps.load(Ordering::SeqCst), "actor stopped");
    Ok(())
}

/// Watches standard input on a thread of its own and ends the process when it reaches its end:
/// the parent holding the pipe's other end has gone (its learner with it), so there is nothing to
/// flush to and no one to stop this actor otherwise.
fn exit_when_stdin_closes() -> Result<()> {
    std::thread::Builder::new().name("parent-watch".into()).spawn(|| {
        use std::io::Read;
        let mut sink = [0u8; 64];
        let mut stdin = std::io::stdin().lock();
        while matches!(stdin.read(&mut sink), Ok(n) if n > 0) {}
        tracing::warn!("standard input closed: the process that started this actor is gone; exiting");
        std::process::exit(1);
    })?;
    Ok(())
}

/// The `--ack-log` file: one JSON line per acknowledged batch, written (unbuffered) as the
/// acknowledgement arrives, so that it survives a SIGKILL of the actor.
#[derive(Debug)]
struct AckLog(Option<std::fs::File>);

impl AckLog {
    fn open(path: Option<&std::path::Path>) -> Result<Self> {
        let file = path
            .map(|p| {
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(p)
                    .with_context(|| format!("opening the ack log {}", p.display()))
            })
            .transpose()?;
        Ok(Self(file))
    }

    fn record(&mut self, name: &str, batch: &pb::ExperienceBatch, ack: &pb::BatchAck) {
        use std::io::Write;
        let Some(f) = self.0.as_mut() else { return };
        let line = serde_json::json!({
            "name": name,
            "actor_id": batch.actor_id,
            "seq": batch.seq,
            "steps": batch.steps.len(),
            "stored": ack.stored,
            "log_position": ack.log_position,
            "epsilon": batch.epsilon,
        });
        if let Err(e) = f.write_all(format!("{line}\n").as_bytes()) {
            tracing::warn!("writing the ack log: {e}");
        }
    }
}

/// Waits between failed registrations and between failed streams: 0.5 s doubling to 30 s, used
/// with ±25 % jitter; a stream's is back to the start once a batch is acknowledged.
fn retry_backoff() -> Backoff {
    Backoff::new(Duration::from_millis(500), Duration::from_secs(30))
}

/// How a stream of batches ended.
#[derive(Debug)]
enum StreamEnd {
    /// Stopped and flushed.
    Done,
    /// The learner does not know this registration (it restarted): register again now.
    Reregister,
    /// Anything else: wait (backoff), then reconnect.
    Failed,
}

/// Streams outbox batches, re-registering and re-sending after any failure, with backoff; after
/// stop, flushes (the caller bounds how long).
async fn send_loop(
    opts: &ActorOptions,
    token: &Option<String>,
    link: &Arc<Link>,
    mut client: Client,
    mut reg: pb::RegisterResponse,
    rng: &mut ChaCha8Rng,
    ack_log: &mut AckLog,
) {
    let mut seq = 0u64;
    let mut limits = Limits::from_register(&reg);
    let mut backoff = retry_backoff();
    loop {
        let (tx, rx) = tokio::sync::mpsc::channel::<pb::ExperienceBatch>(4);
        let mut req = tonic::Request::new(tokio_stream::wrappers::ReceiverStream::new(rx));
        if let Ok(id) = reg.actor_id.parse() {
            req.metadata_mut().insert(ACTOR_ID_HEADER, id);
        }
        let end = match client.stream_experience(req).await {
            Ok(r) => stream_batches(opts, link, &reg, &mut seq, &mut limits, tx, r.into_inner(), ack_log, &mut backoff).await,
            Err(status) => {
                tracing::warn!(code = ?status.code(), learner_says = %status.message(), "experience stream refused");
                if status.code() == tonic::Code::FailedPrecondition { StreamEnd::Reregister } else { StreamEnd::Failed }
            }
        };
        link.connected.store(false, Ordering::SeqCst);
        match end {
            StreamEnd::Done => return,
            StreamEnd::Reregister => {}
            StreamEnd::Failed => {
                let wait = backoff.next_wait_jittered(rng);
                tracing::info!(retry_in_secs = format!("{:.1}", wait.as_secs_f64()), "reconnecting after a wait");
                wait_to_retry(link, wait).await;
            }
        }
        match reconnect(opts, token, link, rng).await {
            Some((c, r)) => (client, reg) = (c, r),
            None => return,
        }
        limits = Limits::from_register(&reg);
    }
}

/// Sends the outbox's batches on one stream, front first, each once its predecessor is
/// acknowledged: nothing acknowledged is kept, nothing unacknowledged is lost.
#[allow(clippy::too_many_arguments)]
async fn stream_batches(
    opts: &ActorOptions,
    link: &Link,
    reg: &pb::RegisterResponse,
    seq: &mut u64,
    limits: &mut Limits,
    tx: tokio::sync::mpsc::Sender<pb::ExperienceBatch>,
    mut acks: tonic::Streaming<pb::BatchAck>,
    ack_log: &mut AckLog,
    backoff: &mut Backoff,
) -> StreamEnd {
    loop {
        let front = {
            let mut ob = link.outbox.lock().expect("outbox lock");
            fit_front(&mut ob, *limits);
            ob.batches.front().cloned()
        };
        let Some((steps, episodes, epsilon, version)) = front else {
            if link.stop.load(Ordering::SeqCst) && link.stepper_done.load(Ordering::SeqCst) {
                return StreamEnd::Done;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
            continue;
        };
        *seq += 1;
        let dropped = std::mem::take(&mut link.outbox.lock().expect("outbox lock").dropped);
        let batch = pb::ExperienceBatch {
            actor_id: reg.actor_id.clone(),
            seq: *seq,
            steps,
            episodes,
            weights_version: version,
            epsilon,
            dropped_steps: dropped,
            demonstration: opts.demonstrate.is_some(),
        };
        if tx.send(batch.clone()).await.is_err() {
            return StreamEnd::Failed;
        }
        match acks.message().await {
            Ok(Some(ack)) => {
                let mut ob = link.outbox.lock().expect("outbox lock");
                if let Some((s, _, _, _)) = ob.batches.pop_front() {
                    ob.steps -= s.len();
                }
                drop(ob);
                link.note_ack();
                backoff.reset();
                ack_log.record(&opts.name, &batch, &ack);
            }
            Ok(None) => {
                tracing::warn!("the learner ended the experience stream without a reason");
                return StreamEnd::Failed;
            }
            Err(status) => return refused(link, limits, &batch, &status),
        }
    }
}

/// Cuts the outbox's front batch to `limits` if it is over them; drops (and counts) a batch with
/// a step that cannot fit at all.
fn fit_front(ob: &mut Outbox, limits: Limits) {
    while let Some((steps, episodes, _, _)) = ob.batches.front() {
        if fits(steps, episodes, limits) {
            return;
        }
        let (steps, episodes, epsilon, version) = ob.batches.pop_front().expect("checked");
        let n = steps.len();
        match split(steps, episodes, limits) {
            Ok(pieces) => {
                tracing::debug!(
                    steps = n,
                    pieces = pieces.len(),
                    max_message_bytes = limits.max_bytes,
                    "batch split to fit the learner's limits"
                );
                for (s, e) in pieces.into_iter().rev() {
                    ob.batches.push_front((s, e, epsilon, version));
                }
                return;
            }
            Err(e) => {
                ob.steps -= n;
                ob.dropped += n as u64;
                tracing::error!(
                    step_bytes = e.bytes,
                    max_message_bytes = e.limit,
                    "a step is larger than the learner accepts (service.max_message_bytes): dropping its batch of {n} steps"
                );
            }
        }
    }
}

/// Handles the learner's refusal of `batch` (the outbox's front): logs the learner's reason;
/// drops a batch the learner will never take; asks for smaller pieces when it was too large.
fn refused(link: &Link, limits: &mut Limits, batch: &pb::ExperienceBatch, status: &tonic::Status) -> StreamEnd {
    let (code, says) = (status.code(), status.message());
    let drop_front = |why: &str| {
        let mut ob = link.outbox.lock().expect("outbox lock");
        if let Some((s, _, _, _)) = ob.batches.pop_front() {
            ob.steps -= s.len();
            ob.dropped += s.len() as u64;
        }
        tracing::error!(seq = batch.seq, steps = batch.steps.len(), learner_says = %says, "the learner refused a batch ({why}); its steps are dropped and counted");
    };
    match code {
        tonic::Code::InvalidArgument => drop_front("invalid"),
        tonic::Code::ResourceExhausted if batch.steps.len() > 1 => {
            // The learner's limit is below what it announced (or the batch's other fields grew):
            // send halves from now on.
            let bytes = batch.steps.iter().map(prost::Message::encoded_len).sum::<usize>();
            limits.max_bytes = limits.max_bytes.min(bytes / 2 + 4096 + 1);
            limits.max_steps = limits.max_steps.min(batch.steps.len() / 2).max(1);
            tracing::warn!(learner_says = %says, max_message_bytes = limits.max_bytes, max_batch_steps = limits.max_steps, "the learner refused a batch as too large; sending smaller batches");
        }
        tonic::Code::ResourceExhausted => drop_front("too large, a single step"),
        tonic::Code::FailedPrecondition => {
            tracing::info!(learner_says = %says, "the learner does not know this registration (it restarted?): registering again");
            return StreamEnd::Reregister;
        }
        _ => tracing::warn!(code = ?code, learner_says = %says, "experience stream ended"),
    }
    StreamEnd::Failed
}

async fn reconnect(
    opts: &ActorOptions,
    token: &Option<String>,
    link: &Link,
    rng: &mut ChaCha8Rng,
) -> Option<(Client, pb::RegisterResponse)> {
    let r = register(opts, token, link, opts.envs, rng).await?;
    tracing::info!(actor_id = %r.1.actor_id, run_env_steps = r.1.run_env_steps, "reconnected");
    link.note_run_env_steps(r.1.run_env_steps);
    link.actor_id.lock().expect("actor id lock").clone_from(&r.1.actor_id);
    link.connected.store(true, Ordering::SeqCst);
    Some(r)
}

/// Polls for new weights every second; never blocks the stepping thread.
async fn weights_loop(opts: ActorOptions, token: Option<String>, link: Arc<Link>, mut client: Client, shape: NetShape) {
    let mut failing = false;
    loop {
        if link.stop.load(Ordering::SeqCst) {
            return;
        }
        let have = link.acting_version.load(Ordering::SeqCst);
        let actor_id = link.actor_id.lock().expect("actor id lock").clone();
        match client.get_weights(pb::GetWeightsRequest { actor_id: actor_id.clone(), have_version: have }).await {
            Ok(w) => {
                if std::mem::take(&mut failing) {
                    link.learner_back.store(true, Ordering::SeqCst);
                }
                let w = w.into_inner();
                link.note_run_env_steps(w.run_env_steps);
                // Any other version is newer: versions only grow within a run, also across the
                // learner's restarts, and a learner of another run starts its own.
                if !w.safetensors.is_empty() && w.version != have {
                    match agent::weights::from_safetensors(shape, &w.safetensors, "") {
                        Ok(params) => *link.fresh_weights.lock().expect("weights lock") = Some((w.version, params)),
                        Err(err) => tracing::warn!(%err, version = w.version, "weights refused"),
                    }
                }
            }
            Err(_) => {
                failing = true;
                // The learner may be restarting: try a new connection next time.
                if let Ok(c) = connect(&opts.learner, token.clone()).await {
                    client = c;
                }
            }
        }
        sleep_unless_stopped(&link, Duration::from_secs(1)).await;
    }
}

/// A demonstrator's pace: it needs no weights and costs no inference, so unchecked it would
/// outrun the learning actors many times over, on the cores the learner and they need. Every
/// second it asks the learner's Status and pauses the stepping thread while the run's
/// demonstrations (all demonstrators') have caught up with its learning actors' steps, except
/// while the learner waits for demonstrations to pre-train on (`agent.demo_pretrain_updates`).
async fn pace_loop(opts: ActorOptions, token: Option<String>, link: Arc<Link>, mut client: Client) {
    loop {
        if link.stop.load(Ordering::SeqCst) {
            link.demo_pause.store(false, Ordering::SeqCst);
            return;
        }
        match client.status(pb::StatusRequest {}).await {
            Ok(st) => {
                let st = st.into_inner();
                let pause = st.demo_pretrain_updates_left == 0 && st.demo_transitions_received >= st.env_steps;
                link.demo_pause.store(pause, Ordering::SeqCst);
            }
            Err(_) => {
                // A learner away or restarting: drive (the outbox buffers) and reconnect.
                link.demo_pause.store(false, Ordering::SeqCst);
                if let Ok(c) = connect(&opts.learner, token.clone()).await {
                    client = c;
                }
            }
        }
        sleep_unless_stopped(&link, Duration::from_secs(1)).await;
    }
}

async fn progress_loop(link: Arc<Link>) {
    let mut last = (Instant::now(), 0u64);
    loop {
        tokio::time::sleep(Duration::from_secs(10)).await;
        let steps = link.env_steps.load(Ordering::SeqCst);
        let rate = (steps - last.1) as f64 / last.0.elapsed().as_secs_f64();
        last = (Instant::now(), steps);
        let ob = link.outbox.lock().expect("outbox lock");
        tracing::info!(
            env_steps = steps,
            steps_per_sec = format!("{rate:.0}"),
            weights_version = link.acting_version.load(Ordering::SeqCst),
            connected = link.connected.load(Ordering::SeqCst),
            buffered_steps = ob.steps,
            waited_for_learner_secs = format!("{:.1}", link.waited_micros.load(Ordering::Relaxed) as f64 / 1e6),
            "progress"
        );
    }
}
