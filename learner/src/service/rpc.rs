//! The gRPC service (`hybriddrive.v1.Learner`): registration, experience ingestion, weight
//! distribution and status.
//!
//! Every stream the learner ends for a reason ends with a status naming it: a batch refused by
//! validation (`INVALID_ARGUMENT`, or `RESOURCE_EXHAUSTED` for too many steps), a message over
//! `service.max_message_bytes` (`RESOURCE_EXHAUSTED`) or one that does not decode
//! (`INVALID_ARGUMENT`), an unknown actor id (`FAILED_PRECONDITION`: register again), a stopping
//! or failed learner (`UNAVAILABLE`). Refusals are counted (`batches_rejected`, per actor and per
//! kind) and logged at WARN once per actor and kind. Nothing of a refused batch is stored, and no
//! other actor notices.
//!
//! With `service.durability = "ack"`, a batch is written to the replay log in the order it enters
//! the replay and acknowledged once the log is synced up to it (group commit: see `storage::replay_log`).

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use proto::v1 as pb;
use proto::v1::learner_server::Learner;
use tokio_stream::{Stream, StreamExt};
use tonic::{Code, Request, Response, Status, Streaming};

use crate::service::validate::{self, Expect, Reject};
use crate::shared_state::{ActorRecord, EpisodeOutcome, Shared};
use crate::storage::replay::StepRecord;
use crate::storage::replay_log;
use crate::telemetry::records::{EpisodeRecord, derived_outcome};

pub use crate::service::validate::MAX_STEPS_PER_BATCH;

/// The first actor index of demonstrators (learning actors count from 0).
pub const DEMONSTRATOR_INDEX: u32 = 1 << 16;

/// The service.
#[derive(Debug, Clone)]
pub struct LearnerService {
    pub shared: Arc<Shared>,
}

type AckStream = Pin<Box<dyn Stream<Item = Result<pb::BatchAck, Status>> + Send>>;

#[tonic::async_trait]
impl Learner for LearnerService {
    async fn register(&self, req: Request<pb::RegisterRequest>) -> Result<Response<pb::RegisterResponse>, Status> {
        let r = req.into_inner();
        if r.protocol != pb::PROTOCOL {
            return Err(Status::failed_precondition(format!(
                "protocol {} is not supported: this learner speaks protocol {}",
                r.protocol,
                pb::PROTOCOL
            )));
        }
        if r.envs == 0 || r.envs > 4096 {
            return Err(Status::invalid_argument(format!("envs = {} must be 1..=4096", r.envs)));
        }
        let s = &self.shared;
        if s.cfg.env.vector.is_some() && r.vector_layout != sim_core::sensor::LAYOUT_VERSION {
            let theirs = if r.vector_layout.is_empty() {
                "none (it predates the vector sensor)".to_owned()
            } else {
                format!("`{}`", r.vector_layout)
            };
            return Err(Status::failed_precondition(format!(
                "vector_layout: this run observes the vector sensor in layout `{}`, the actor writes {theirs}: run an actor of this learner's version",
                sim_core::sensor::LAYOUT_VERSION
            )));
        }
        if !r.demonstrator.is_empty() && s.cfg.agent.demo_capacity == 0 {
            return Err(Status::failed_precondition(format!(
                "demonstrator `{}`: this run keeps no demonstrations ([agent] demo_capacity = 0)",
                r.demonstrator
            )));
        }
        let n = s.registrations.fetch_add(1, Ordering::SeqCst);
        let mut actors = s.actors.lock().expect("actors lock");
        // An actor that comes back under the same name (reconnected, or restarted) reuses its
        // record, index (and so exploration rate) included; its earlier registration ends.
        let existing = (!r.name.is_empty()).then(|| actors.iter().position(|a| a.name == r.name)).flatten();
        // Learning actors are numbered 0, 1, … among themselves (Ape-X's per-actor ε), whenever
        // demonstrators register; demonstrators from DEMONSTRATOR_INDEX on.
        let demonstrator = !r.demonstrator.is_empty();
        let fresh_index = {
            let peers = actors.iter().filter(|a| a.demonstrator.is_empty() != demonstrator).count() as u32;
            if demonstrator { DEMONSTRATOR_INDEX + peers } else { peers }
        };
        let index = existing.map_or(fresh_index, |k| actors[k].index);
        let id = format!("{}-a{}-{}", s.run_id, index, n);
        let ended = match existing {
            Some(k) => {
                let a = &mut actors[k];
                let old = std::mem::replace(&mut a.id, id.clone());
                a.envs = r.envs;
                a.demonstrator.clone_from(&r.demonstrator);
                a.registrations += 1;
                a.last_seen = Instant::now();
                a.last_seq = None;
                a.env_positions = vec![None; r.envs as usize];
                Some(old)
            }
            None => {
                let mut record = ActorRecord::new(id.clone(), r.name.clone(), index, r.envs);
                record.demonstrator.clone_from(&r.demonstrator);
                actors.push(record);
                None
            }
        };
        let first_life = ended.is_none() && !s.resumed;
        drop(actors);
        let run_env_steps = s.counters.lock().expect("counters lock").env_steps;
        if let Some(old) = ended {
            // The old registration's half-built transitions will never be completed.
            s.replay.lock().expect("replay lock").end_streams_of(&old);
        }
        tracing::info!(actor_id = %id, name = %r.name, index, envs = r.envs, demonstrator = %r.demonstrator, "actor registered");
        let env_toml = toml::to_string(&s.cfg.env).map_err(|e| Status::internal(e.to_string()))?;
        let agent_toml = toml::to_string(&s.cfg.agent).map_err(|e| Status::internal(e.to_string()))?;
        let (map_name, map_text, map_hash) = s.map.as_ref().map_or_else(Default::default, |m| (m.name.clone(), m.text.clone(), m.hash));
        Ok(Response::new(pb::RegisterResponse {
            actor_id: id,
            actor_index: index,
            run_id: s.run_id.clone(),
            env_config_toml: env_toml,
            agent_config_toml: agent_toml,
            weights_version: s.current_weights().version,
            max_message_bytes: s.cfg.service.max_message_bytes as u64,
            max_batch_steps: MAX_STEPS_PER_BATCH as u32,
            run_env_steps,
            episode_stream: episode_stream(first_life, run_env_steps, n),
            map_name,
            map_text,
            map_hash,
        }))
    }

    type StreamExperienceStream = AckStream;

    async fn stream_experience(&self, req: Request<Streaming<pb::ExperienceBatch>>) -> Result<Response<AckStream>, Status> {
        let shared = self.shared.clone();
        let peer = req.remote_addr().map_or_else(|| "unknown peer".to_owned(), |a| a.ip().to_string());
        let declared = req.metadata().get(proto::client::ACTOR_ID_HEADER).and_then(|v| v.to_str().ok()).map(str::to_owned);
        let mut incoming = req.into_inner();
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        // Batches are stored as they arrive; their acknowledgements wait for durability in
        // order, beside, so that a client with several batches in flight gets them committed
        // together.
        let (ordered, mut pending) = tokio::sync::mpsc::channel::<Result<Stored, Status>>(8);
        {
            let shared = shared.clone();
            tokio::spawn(async move {
                while let Some(item) = pending.recv().await {
                    let result = match item {
                        Ok(stored) => acknowledge(&shared, stored).await,
                        Err(status) => Err(status),
                    };
                    let stop = result.is_err();
                    if tx.send(result).await.is_err() || stop {
                        break;
                    }
                }
            });
        }
        tokio::spawn(async move {
            let mut stream = OpenStream { shared: shared.clone(), record: None };
            if let Some(id) = &declared {
                stream.attach(id);
            }
            while let Some(item) = incoming.next().await {
                // The replay ratio holds: nothing more is stored while the learner is behind.
                let admission = shared.backpressure.admit(|| shared.may_store_a_batch()).await;
                let next = take(&shared, &mut stream, &peer, item);
                note_held(&shared, stream.record, admission.waited());
                // Let the next held stream through before waiting on the acknowledgements.
                drop(admission);
                // A refusal ends the stream; so does a stream that ended (nothing to answer).
                let Some(result) = next else { break };
                let last = result.is_err();
                if ordered.send(result).await.is_err() || last {
                    break;
                }
            }
        });
        Ok(Response::new(Box::pin(tokio_stream::wrappers::ReceiverStream::new(rx))))
    }

    async fn get_weights(&self, req: Request<pb::GetWeightsRequest>) -> Result<Response<pb::Weights>, Status> {
        let r = req.into_inner();
        let w = self.shared.current_weights();
        if !r.actor_id.is_empty() {
            touch(&self.shared, &r.actor_id, |a| a.weights_version = r.have_version);
        }
        // Any other version than the current one is stale: versions of this run only grow (also
        // across restarts, see `versions`), and one from another run is no use either.
        let bytes = if r.have_version != w.version { w.bytes.as_ref().clone() } else { Vec::new() };
        let run_env_steps = self.shared.counters.lock().expect("counters lock").env_steps;
        Ok(Response::new(pb::Weights { version: w.version, safetensors: bytes, run_env_steps }))
    }

    async fn status(&self, _req: Request<pb::StatusRequest>) -> Result<Response<pb::StatusResponse>, Status> {
        Ok(Response::new(status(&self.shared)))
    }
}

/// The episode-seed stream of a registration: 0 for the first life of a name in a fresh run (a
/// fresh run with a seed is bit-identical), else one that no earlier registration of this run
/// had: the run's env steps so far (they only grow, across resumes too) with this process's
/// registration count, so that a restarted actor never replays its first life's episodes.
fn episode_stream(first_life: bool, run_env_steps: u64, registration: u64) -> u64 {
    if first_life { 0 } else { 1 + (run_env_steps << 16 | (registration & 0xffff)) }
}

/// An experience stream, counted in its actor's `open_streams` while it lasts.
struct OpenStream {
    shared: Arc<Shared>,
    /// Index of the actor's record.
    record: Option<usize>,
}

impl OpenStream {
    /// Binds the stream to the actor whose current registration is `id`; false if unknown.
    fn attach(&mut self, id: &str) -> bool {
        let mut actors = self.shared.actors.lock().expect("actors lock");
        match actors.iter().position(|a| a.id == id) {
            Some(k) => {
                actors[k].open_streams += 1;
                actors[k].last_seen = Instant::now();
                self.record = Some(k);
                true
            }
            None => false,
        }
    }
}

impl Drop for OpenStream {
    fn drop(&mut self) {
        if let Some(k) = self.record {
            let mut actors = self.shared.actors.lock().expect("actors lock");
            actors[k].open_streams = actors[k].open_streams.saturating_sub(1);
        }
    }
}

/// What a stream answers to the message it received, once the replay ratio let it through: the
/// batch stored, or the refusal that ends the stream; `None` when the stream merely ended. Binds
/// the stream to its actor on its first batch.
fn take(shared: &Shared, stream: &mut OpenStream, peer: &str, item: Result<pb::ExperienceBatch, Status>) -> Option<Result<Stored, Status>> {
    if shared.stopping() {
        // Refuse new work while stopping: the actor keeps the batch and resends it.
        return Some(Err(Status::unavailable("the learner is stopping; retry shortly")));
    }
    let batch = match item {
        Ok(b) => b,
        Err(status) => return undecodable(shared, stream, peer, &status).map(Err),
    };
    if stream.record.is_none() && !stream.attach(&batch.actor_id) {
        tracing::debug!(actor_id = %batch.actor_id, "batch from an unknown actor id: asked to register");
        return Some(Err(unknown_actor(&batch.actor_id)));
    }
    Some(store(shared, batch))
}

/// Adds the time a stream was held to the run's and its actor's `held_secs`.
fn note_held(shared: &Shared, record: Option<usize>, waited: Option<Duration>) {
    let Some(secs) = waited.map(|w| w.as_secs_f64()) else { return };
    shared.stats.lock().expect("stats lock").held_secs += secs;
    if let Some(k) = record {
        shared.actors.lock().expect("actors lock")[k].held_secs += secs;
    }
}

fn unknown_actor(id: &str) -> Status {
    Status::failed_precondition(format!(
        "unknown actor id `{id}`: register first (ids of an earlier registration or learner process are not accepted)"
    ))
}

/// Why a stream's next message could not be received.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ReceiveFailure {
    /// Longer than `service.max_message_bytes`.
    TooLarge,
    /// Bytes that are not the message (or a message cut short by the end of its stream).
    Undecodable,
    /// The peer went away, reset the stream, or the connection broke: nothing to refuse.
    StreamEnded,
}

/// Tells the decoder's refusals from the connection's failures by the status's type, not its text:
/// tonic's decoder makes its refusals itself (`OUT_OF_RANGE` or `RESOURCE_EXHAUSTED` for the size,
/// `INTERNAL` for what prost cannot decode), with no underlying error, while a failure of the
/// connection reaches the handler through `Status::from_error`, which keeps the h2, hyper or I/O
/// error as the status's `source`.
fn receive_failure(status: &Status) -> ReceiveFailure {
    if std::error::Error::source(status).is_some() {
        return ReceiveFailure::StreamEnded;
    }
    match status.code() {
        Code::OutOfRange | Code::ResourceExhausted => ReceiveFailure::TooLarge,
        Code::Internal => ReceiveFailure::Undecodable,
        _ => ReceiveFailure::StreamEnded,
    }
}

/// Turns a message that could not be received into the refusal to send back, counted and logged,
/// or `None` when the stream merely ended.
fn undecodable(shared: &Shared, stream: &OpenStream, peer: &str, status: &Status) -> Option<Status> {
    let msg = status.message();
    let (kind, refusal) = match receive_failure(status) {
        ReceiveFailure::TooLarge => (
            "too_large",
            Status::resource_exhausted(format!(
                "message too large: {msg} (service.max_message_bytes = {}; split batches below it)",
                shared.cfg.service.max_message_bytes
            )),
        ),
        ReceiveFailure::Undecodable => ("undecodable", Status::invalid_argument(format!("undecodable message: {msg}"))),
        ReceiveFailure::StreamEnded => {
            tracing::debug!(%status, "experience stream ended");
            return None;
        }
    };
    let counter = if kind == "too_large" { &shared.refused.too_large } else { &shared.refused.undecodable };
    counter.fetch_add(1, Ordering::Relaxed);
    shared.counters.lock().expect("counters lock").batches_rejected += 1;
    let who = stream.record.map(|k| {
        let mut actors = shared.actors.lock().expect("actors lock");
        let a = &mut actors[k];
        a.rejected_batches += 1;
        (a.id.clone(), a.warned.insert(kind))
    });
    let first = match &who {
        Some((_, first)) => *first,
        None => {
            let mut peers = shared.warned_peers.lock().expect("peers lock");
            if peers.len() > 10_000 {
                peers.clear();
            }
            peers.insert(format!("{peer} {kind}"))
        }
    };
    let actor = who.map_or_else(|| format!("unregistered client at {peer}"), |w| w.0);
    if first {
        tracing::warn!(%actor, status = %refusal.message(), "experience stream refused (further refusals of this kind from it: DEBUG)");
    } else {
        tracing::debug!(%actor, status = %refusal.message(), "experience stream refused");
    }
    Some(refusal)
}

/// Updates an actor's record if it is known.
fn touch(shared: &Shared, id: &str, f: impl FnOnce(&mut ActorRecord)) -> bool {
    let mut actors = shared.actors.lock().expect("actors lock");
    match actors.iter_mut().find(|a| a.id == id) {
        Some(a) => {
            a.last_seen = Instant::now();
            f(a);
            true
        }
        None => false,
    }
}

/// What batches are checked against in this run.
fn expect(shared: &Shared) -> Expect {
    Expect {
        frame_bytes: shared.frame_bytes,
        width: shared.shape.width,
        height: shared.shape.height,
        channels: shared.shape.channels,
        actions: shared.shape.actions as u32,
        path_features: shared.cfg.agent.path_features,
        vector_len: shared.cfg.vector_len(),
        bounds: crate::service::bounds::Bounds::of(&shared.cfg.env),
    }
}

/// A batch in the replay (and written to the log), not yet acknowledged.
#[derive(Debug)]
struct Stored {
    batch: pb::ExperienceBatch,
    stored: u64,
    /// Its position in the replay log.
    position: Option<u64>,
    learner_step: u64,
    env_steps: u64,
    first_episode: u64,
}

/// Validates one batch and stores it (replay and log), or returns the refusal.
fn store(shared: &Shared, b: pb::ExperienceBatch) -> Result<Stored, Status> {
    let checked = {
        let mut actors = shared.actors.lock().expect("actors lock");
        let Some(a) = actors.iter_mut().find(|a| a.id == b.actor_id) else { return Err(unknown_actor(&b.actor_id)) };
        a.last_seen = Instant::now();
        match validate::check(&expect(shared), a, &b) {
            Ok(positions) => {
                validate::accept(a, &b, positions);
                Ok(())
            }
            Err(reject) => {
                a.rejected_batches += 1;
                let kind = if matches!(reject, Reject::TooLarge(_)) { "too_large" } else { "invalid" };
                Err((reject, a.warned.insert(kind)))
            }
        }
    };
    if let Err((reject, first)) = checked {
        {
            let mut c = shared.counters.lock().expect("counters lock");
            c.batches_rejected += 1;
            c.transitions_rejected += b.steps.iter().filter(|s| s.t > 0).count() as u64;
        }
        let status = match reject {
            Reject::Invalid(m) => Status::invalid_argument(m),
            Reject::TooLarge(m) => Status::resource_exhausted(m),
        };
        shared.note_refusal(status.message());
        if first {
            tracing::warn!(actor_id = %b.actor_id, %status, "batch refused (further refusals of this kind from this actor: DEBUG)");
        } else {
            tracing::debug!(actor_id = %b.actor_id, %status, "batch refused");
        }
        return Err(status);
    }
    if let Some(reason) = shared.failure() {
        return Err(Status::unavailable(format!("the learner has stopped training ({reason}); it acknowledges nothing more")));
    }
    let records: Vec<StepRecord<'_>> = b
        .steps
        .iter()
        .map(|s| {
            let obs = s.obs.as_ref().expect("validated");
            StepRecord {
                env: s.env,
                episode: s.episode,
                t: s.t,
                image: &obs.image,
                speed: obs.speed,
                d: obs.d,
                path: obs.path.as_slice().try_into().unwrap_or_default(),
                vector: std::borrow::Cow::Borrowed(&obs.vector),
                action: s.action,
                reward: s.reward,
                terminated: s.terminated,
                truncated: s.truncated,
            }
        })
        .collect();
    let demonstration = b.demonstration;
    let payload = shared.log.as_ref().map(|_| {
        let encode = if demonstration { replay_log::format::encode_demonstrations } else { replay_log::format::encode };
        encode(&b.actor_id, b.episodes.len() as u32, &records)
    });
    let env_steps = b.steps.iter().filter(|s| s.t > 0).count() as u64;
    let (stored, position, learner_step, total_steps, first_episode, replay_len, stored_in_all) = {
        let mut replay = shared.replay.lock().expect("replay lock");
        // The log's order is the replay's: append under the replay's lock.
        let position = match (&shared.log, &payload) {
            (Some(log), Some(p)) => Some(log.append(p).map_err(|e| refuse_unlogged(shared, &e))?),
            _ => None,
        };
        let stored =
            if demonstration { replay.add_demo_steps(&b.actor_id, &records) } else { replay.add_steps(&b.actor_id, &records) } as u64;
        if let Some(log) = &shared.log {
            log.note_frames(replay.log_frame_end(), replay.log_first_live_frame());
        }
        let mut c = shared.counters.lock().expect("counters lock");
        if demonstration {
            // Not the agent's experience: neither the run's env steps (its budget, ε) nor its
            // replay ratio count them, and its episodes are not the agent's.
            c.demo_transitions_received += env_steps;
            c.demo_transitions_stored += stored;
        } else {
            c.transitions_received += env_steps;
            c.transitions_stored += stored;
            c.env_steps += env_steps;
        }
        let first = c.episodes;
        if !demonstration {
            c.episodes += b.episodes.len() as u64;
        }
        if let Some(p) = position {
            c.replay_log_position = p;
        }
        (stored, position, c.learner_step, c.env_steps, first, replay.len(), c.transitions_stored)
    };
    shared.fix_ratio_baseline(replay_len, stored_in_all);
    shared.data_arrived.1.notify_one();
    Ok(Stored { batch: b, stored, position, learner_step, env_steps: total_steps, first_episode })
}

/// Waits until a stored batch is durable (with `durability = "ack"`), then does its bookkeeping
/// and returns its acknowledgement.
async fn acknowledge(shared: &Shared, s: Stored) -> Result<pb::BatchAck, Status> {
    let Stored { batch: b, stored, position, learner_step, env_steps: total_steps, first_episode } = s;
    if let (Some(log), Some(p)) = (&shared.log, position) {
        log.durable(p).await.map_err(|e| refuse_unlogged(shared, &e))?;
    }
    touch(shared, &b.actor_id, |a| {
        a.transitions += stored;
        a.weights_version = b.weights_version;
        a.epsilon = b.epsilon;
        a.dropped_steps += b.dropped_steps;
    });
    if b.demonstration {
        // A demonstrator's episodes are the teacher's, not the agent's: they stay out of the
        // episode log and the statistics.
        return Ok(pb::BatchAck {
            seq: b.seq,
            stored: stored as u32,
            weights_version: shared.current_weights().version,
            log_position: position.unwrap_or(0),
        });
    }
    let time_secs = shared.run_secs();
    for (k, e) in b.episodes.iter().enumerate() {
        let line = EpisodeRecord {
            time_secs,
            episode_index: first_episode + k as u64 + 1,
            actor_id: b.actor_id.clone(),
            env: e.env,
            episode_return: f64::from(e.episode_return),
            steps: e.steps,
            arrived: e.arrived,
            collision: (!e.collision.is_empty()).then(|| e.collision.clone()),
            scenario: e.scenario.clone(),
            hazard: (!e.hazard.is_empty()).then(|| e.hazard.clone()),
            // An actor that predates the outcome field sends it empty: derived from its flags.
            outcome: if e.outcome.is_empty() { derived_outcome(e.arrived, !e.collision.is_empty()).to_owned() } else { e.outcome.clone() },
            learner_step,
            env_steps: total_steps,
        };
        if let Err(err) = shared.metrics.episode(&line) {
            tracing::warn!(%err, "writing episodes.jsonl");
        }
    }
    shared.push_episodes(b.episodes.iter().map(|e| EpisodeOutcome {
        episode_return: f64::from(e.episode_return),
        arrived: e.arrived,
        collided: !e.collision.is_empty(),
    }));
    Ok(pb::BatchAck {
        seq: b.seq,
        stored: stored as u32,
        weights_version: shared.current_weights().version,
        log_position: position.unwrap_or(0),
    })
}

/// A batch that could not be made durable is not acknowledged: `UNAVAILABLE` (the actor keeps it
/// and retries). A failed sync means the learner cannot promise anything any more.
fn refuse_unlogged(shared: &Shared, e: &replay_log::LogError) -> Status {
    if matches!(e, replay_log::LogError::Failed(_)) {
        shared.fail(e.to_string());
    } else {
        tracing::error!("{e}: batch not acknowledged");
    }
    let status = Status::unavailable(format!("the learner could not make the batch durable: {e}"));
    shared.note_refusal(status.message());
    status
}

/// The status of the run.
#[must_use]
pub fn status(shared: &Shared) -> pb::StatusResponse {
    let c = shared.counters.lock().expect("counters lock").clone();
    let st = *shared.stats.lock().expect("stats lock");
    let (replay_size, replay_bytes, capacity, evicted, demo_size, demo_capacity) = {
        let r = shared.replay.lock().expect("replay lock");
        (r.len() as u64, r.bytes(), r.capacity() as u64, r.evicted(), r.demo_len() as u64, r.demo_capacity() as u64)
    };
    let log = shared.log.as_ref().map(replay_log::ReplayLog::stats).unwrap_or_default();
    let version = shared.current_weights().version;
    let timeout = Duration::from_secs(shared.cfg.service.actor_timeout_secs);
    let actors = shared
        .actors
        .lock()
        .expect("actors lock")
        .iter()
        .map(|a| pb::ActorStatus {
            actor_id: a.id.clone(),
            name: a.name.clone(),
            actor_index: a.index,
            last_seen_secs: a.last_seen.elapsed().as_secs_f64(),
            weights_version: a.weights_version,
            // An actor ahead of this learner holds weights of another run: all of this run's are
            // news to it.
            version_lag: if a.weights_version <= version { version - a.weights_version } else { version },
            transitions: a.transitions,
            rejected_batches: a.rejected_batches,
            connected: a.connected(timeout),
            open_streams: a.open_streams,
            registrations: a.registrations,
            dropped_steps: a.dropped_steps,
            epsilon: a.epsilon,
            held_secs: a.held_secs,
            demonstrator: a.demonstrator.clone(),
        })
        .collect();
    let window = shared.recent_episodes.lock().expect("episodes lock");
    let n = window.len().max(1) as f64;
    let episodes = pb::EpisodeStats {
        window: window.len() as u32,
        mean_return: window.iter().map(|e| e.episode_return).sum::<f64>() / n,
        completion_rate: window.iter().filter(|e| e.arrived).count() as f64 / n,
        collision_rate: window.iter().filter(|e| e.collided).count() as f64 / n,
        episodes_total: c.episodes,
    };
    pb::StatusResponse {
        run_id: shared.run_id.clone(),
        uptime_secs: shared.started.elapsed().as_secs_f64(),
        learner_step: c.learner_step,
        weights_version: version,
        transitions_received: c.transitions_received,
        transitions_stored: c.transitions_stored,
        transitions_rejected: c.transitions_rejected,
        batches_rejected: c.batches_rejected,
        replay_size,
        replay_capacity: capacity,
        replay_bytes,
        updates_per_sec: st.updates_per_sec,
        env_steps_per_sec: st.env_steps_per_sec,
        actors,
        episodes: Some(episodes),
        loss: st.loss.unwrap_or(f64::NAN),
        mean_q: st.mean_q.unwrap_or(f64::NAN),
        // The schedule at the run's step now (not the last second's report).
        epsilon: f64::from(shared.cfg.epsilon(0, c.env_steps)),
        variant: match shared.cfg.env.variant {
            sim_core::config::Variant::Hybrid => "hybrid".into(),
            sim_core::config::Variant::EndToEnd => "end_to_end".into(),
        },
        durability: shared.cfg.service.durability.name().into(),
        replay_log_bytes: log.bytes,
        replay_log_segments: log.segments,
        replay_log_first_position: log.first_position,
        replay_log_durable_position: log.durable_position,
        transitions_evicted: evicted,
        training_error: shared.failure().map(|f| f.to_string()).unwrap_or_default(),
        checkpoint_error: shared.checkpoint_error.lock().expect("checkpoint error lock").clone().unwrap_or_default(),
        streams_refused_too_large: shared.refused.too_large.load(Ordering::Relaxed),
        streams_refused_undecodable: shared.refused.undecodable.load(Ordering::Relaxed),
        recent_refusal: shared.recent_refusal().unwrap_or_default(),
        env_steps: c.env_steps,
        run_secs: shared.run_secs(),
        held_secs: st.held_secs,
        demo_transitions_received: c.demo_transitions_received,
        demo_transitions_stored: c.demo_transitions_stored,
        demo_replay_size: demo_size,
        demo_replay_capacity: demo_capacity,
        demo_batch_share: st.demo_batch_share,
        demo_share: if demo_size > 0 { f64::from(shared.cfg.demo_share(c.env_steps)) } else { 0.0 },
        margin_loss: st.margin_loss.unwrap_or(f64::NAN),
        demo_pretrain_updates_left: st.pretrain_updates_left,
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    /// The decoder's own refusals carry no underlying error; the connection's failures carry
    /// theirs. The message text decides nothing (a tonic upgrade may reword it).
    #[test]
    fn a_receive_failure_is_told_by_its_source_not_its_text() {
        assert_eq!(receive_failure(&Status::out_of_range("Error, decoded message length too large")), ReceiveFailure::TooLarge);
        assert_eq!(receive_failure(&Status::resource_exhausted("size limit exceeded")), ReceiveFailure::TooLarge);
        assert_eq!(receive_failure(&Status::internal("failed to decode Protobuf message")), ReceiveFailure::Undecodable);
        // Text that used to mean "transport" means nothing without the error under it...
        assert_eq!(receive_failure(&Status::internal("h2 protocol error: reworded")), ReceiveFailure::Undecodable);
        // ...and a connection's error means the stream ended, whatever the code and text.
        for mut status in [Status::internal("anything"), Status::resource_exhausted("anything"), Status::out_of_range("x")] {
            status.set_source(Arc::new(std::io::Error::new(std::io::ErrorKind::ConnectionReset, "reset by peer")));
            assert_eq!(receive_failure(&status), ReceiveFailure::StreamEnded, "{status:?}");
        }
        let from_io = Status::from_error(Box::new(std::io::Error::new(std::io::ErrorKind::BrokenPipe, "broken pipe")));
        assert_eq!(receive_failure(&from_io), ReceiveFailure::StreamEnded);
        assert_eq!(receive_failure(&Status::cancelled("peer went away")), ReceiveFailure::StreamEnded);
    }
}
