//! The gRPC service (`hybriddrive.v1.Learner`): registration, experience ingestion with
//! validation, weight distribution and status. A bad batch is refused whole, with a status naming
//! the problem; it is counted and nothing of it is stored, and no other actor notices.

use std::pin::Pin;
use std::sync::Arc;
use std::time::Instant;

use proto::v1 as pb;
use proto::v1::learner_server::Learner;
use tokio_stream::{Stream, StreamExt};
use tonic::{Request, Response, Status, Streaming};

use crate::records::EpisodeRecord;
use crate::replay::StepRecord;
use crate::state::{ActorRecord, EpisodeOutcome, Shared};
use sim_core::env::PATH_FEATURES;

/// Most steps one batch may carry.
pub const MAX_STEPS_PER_BATCH: usize = 4096;

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
        let mut actors = s.actors.lock().expect("actors lock");
        // An actor that comes back under the same name keeps its index (and exploration rate).
        let index = actors.iter().find(|a| !r.name.is_empty() && a.name == r.name).map_or(actors.len() as u32, |a| a.index);
        let id = format!("{}-a{}-{}", s.run_id, index, actors.len());
        actors.push(ActorRecord {
            id: id.clone(),
            name: r.name.clone(),
            index,
            envs: r.envs,
            last_seen: Instant::now(),
            weights_version: 0,
            transitions: 0,
            rejected_batches: 0,
            epsilon: 1.0,
            dropped_steps: 0,
        });
        drop(actors);
        tracing::info!(actor_id = %id, name = %r.name, index, envs = r.envs, "actor registered");
        let env_toml = toml::to_string(&s.cfg.env).map_err(|e| Status::internal(e.to_string()))?;
        let agent_toml = toml::to_string(&s.cfg.agent).map_err(|e| Status::internal(e.to_string()))?;
        Ok(Response::new(pb::RegisterResponse {
            actor_id: id,
            actor_index: index,
            run_id: s.run_id.clone(),
            env_config_toml: env_toml,
            agent_config_toml: agent_toml,
            weights_version: s.current_weights().version,
            max_message_bytes: s.cfg.service.max_message_bytes as u64,
        }))
    }

    type StreamExperienceStream = AckStream;

    async fn stream_experience(&self, req: Request<Streaming<pb::ExperienceBatch>>) -> Result<Response<AckStream>, Status> {
        let shared = self.shared.clone();
        let mut incoming = req.into_inner();
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        tokio::spawn(async move {
            while let Some(item) = incoming.next().await {
                if shared.stopping() {
                    // Refuse new work while stopping: the actor keeps the batch and resends it.
                    let _ = tx.send(Err(Status::unavailable("the learner is stopping; retry shortly"))).await;
                    break;
                }
                let batch = match item {
                    Ok(b) => b,
                    Err(status) => {
                        tracing::debug!(%status, "experience stream ended");
                        break;
                    }
                };
                let result = ingest(&shared, &batch);
                let stop = result.is_err();
                if tx.send(result).await.is_err() || stop {
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
        let bytes = if r.have_version < w.version { w.bytes.as_ref().clone() } else { Vec::new() };
        Ok(Response::new(pb::Weights { version: w.version, safetensors: bytes }))
    }

    async fn status(&self, _req: Request<pb::StatusRequest>) -> Result<Response<pb::StatusResponse>, Status> {
        Ok(Response::new(status(&self.shared)))
    }
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

/// Why a batch was refused.
#[derive(Debug)]
enum Reject {
    Invalid(String),
    TooLarge(String),
}

/// Checks a whole batch before anything of it is stored.
fn validate(shared: &Shared, b: &pb::ExperienceBatch) -> Result<(), Reject> {
    if b.steps.len() > MAX_STEPS_PER_BATCH {
        return Err(Reject::TooLarge(format!("batch {} has {} steps; at most {MAX_STEPS_PER_BATCH} are accepted", b.seq, b.steps.len())));
    }
    let actions = shared.shape.actions as u32;
    for (i, s) in b.steps.iter().enumerate() {
        let Some(obs) = &s.obs else {
            return Err(Reject::Invalid(format!("batch {} step {i}: no observation", b.seq)));
        };
        if obs.image.len() != shared.frame_bytes {
            let (w, h, c) = (shared.shape.width, shared.shape.height, shared.shape.channels);
            return Err(Reject::Invalid(format!(
                "batch {} step {i}: image has {} bytes; this run's camera is {w}x{h}x{c} = {} bytes",
                b.seq,
                obs.image.len(),
                shared.frame_bytes
            )));
        }
        if s.t > 0 && s.action >= actions {
            return Err(Reject::Invalid(format!("batch {} step {i}: action {} is out of range 0..{actions}", b.seq, s.action)));
        }
        match obs.path.len() {
            0 if shared.cfg.agent.path_features => {
                return Err(Reject::Invalid(format!(
                    "batch {} step {i}: no path features, and this run's network needs them (agent.path_features = true); \
                     update the actor",
                    b.seq
                )));
            }
            0 | PATH_FEATURES => {}
            n => {
                return Err(Reject::Invalid(format!("batch {} step {i}: {n} path features; expected {PATH_FEATURES} or none", b.seq)));
            }
        }
        let path = obs.path.iter().map(|&v| ("path", v));
        for (name, v) in [("reward", s.reward), ("speed", obs.speed), ("d", obs.d)].into_iter().chain(path) {
            if !v.is_finite() {
                return Err(Reject::Invalid(format!("batch {} step {i}: {name} is {v}, not a finite number", b.seq)));
            }
        }
        if s.terminated && s.truncated {
            return Err(Reject::Invalid(format!("batch {} step {i}: terminated and truncated at once", b.seq)));
        }
    }
    for (i, e) in b.episodes.iter().enumerate() {
        if !e.episode_return.is_finite() {
            return Err(Reject::Invalid(format!(
                "batch {} episode summary {i}: return is {}, not a finite number",
                b.seq, e.episode_return
            )));
        }
    }
    if !(b.epsilon.is_finite() && (0.0..=1.0).contains(&b.epsilon)) {
        return Err(Reject::Invalid(format!("batch {}: epsilon {} is outside [0, 1]", b.seq, b.epsilon)));
    }
    Ok(())
}

/// Validates and stores one batch; returns its acknowledgement or the refusal.
fn ingest(shared: &Shared, b: &pb::ExperienceBatch) -> Result<pb::BatchAck, Status> {
    let known = touch(shared, &b.actor_id, |_| {});
    if !known {
        return Err(Status::failed_precondition(format!("unknown actor id `{}`: register first", b.actor_id)));
    }
    if let Err(reject) = validate(shared, b) {
        {
            let mut c = shared.counters.lock().expect("counters lock");
            c.batches_rejected += 1;
            c.transitions_rejected += b.steps.iter().filter(|s| s.t > 0).count() as u64;
        }
        touch(shared, &b.actor_id, |a| a.rejected_batches += 1);
        let status = match reject {
            Reject::Invalid(m) => Status::invalid_argument(m),
            Reject::TooLarge(m) => Status::resource_exhausted(m),
        };
        tracing::warn!(actor_id = %b.actor_id, %status, "batch rejected");
        return Err(status);
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
                action: s.action,
                reward: s.reward,
                terminated: s.terminated,
                truncated: s.truncated,
            }
        })
        .collect();
    let stored = shared.replay.lock().expect("replay lock").add_steps(&b.actor_id, &records) as u64;
    let env_steps = b.steps.iter().filter(|s| s.t > 0).count() as u64;
    let (learner_step, total_steps, first_episode) = {
        let mut c = shared.counters.lock().expect("counters lock");
        c.transitions_received += env_steps;
        c.transitions_stored += stored;
        c.env_steps += env_steps;
        let first = c.episodes;
        c.episodes += b.episodes.len() as u64;
        (c.learner_step, c.env_steps, first)
    };
    touch(shared, &b.actor_id, |a| {
        a.transitions += stored;
        a.weights_version = b.weights_version;
        a.epsilon = b.epsilon;
        a.dropped_steps += b.dropped_steps;
    });
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
    shared.data_arrived.1.notify_one();
    Ok(pb::BatchAck { seq: b.seq, stored: stored as u32, weights_version: shared.current_weights().version })
}

/// The status of the run.
#[must_use]
pub fn status(shared: &Shared) -> pb::StatusResponse {
    let c = shared.counters.lock().expect("counters lock").clone();
    let st = *shared.stats.lock().expect("stats lock");
    let (replay_size, replay_bytes, capacity) = {
        let r = shared.replay.lock().expect("replay lock");
        (r.len() as u64, r.bytes(), r.capacity() as u64)
    };
    let version = shared.current_weights().version;
    let timeout = shared.cfg.service.actor_timeout_secs as f64;
    let actors = shared
        .actors
        .lock()
        .expect("actors lock")
        .iter()
        .map(|a| {
            let seen = a.last_seen.elapsed().as_secs_f64();
            pb::ActorStatus {
                actor_id: a.id.clone(),
                name: a.name.clone(),
                actor_index: a.index,
                last_seen_secs: seen,
                weights_version: a.weights_version,
                version_lag: version.saturating_sub(a.weights_version),
                transitions: a.transitions,
                rejected_batches: a.rejected_batches,
                connected: seen < timeout,
            }
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
        epsilon: st.epsilon,
        variant: match shared.cfg.env.variant {
            sim_core::config::Variant::Hybrid => "hybrid".into(),
            sim_core::config::Variant::EndToEnd => "end_to_end".into(),
        },
    }
}
