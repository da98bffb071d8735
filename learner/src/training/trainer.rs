//! The training thread: decoupled from ingestion, it trains as fast as the replay ratio allows
//! (samples trained per transition inserted; the experience streams wait while it owes more than
//! `service.update_lag_limit` updates, `service/backpressure.rs`), publishes weights every few updates and writes
//! checkpoints on an interval — the first at most 30 s after it starts, so that an early SIGKILL
//! loses little training. A checkpoint that cannot be written is retried with backoff (5 s
//! doubling to 5 min) while training goes on, and shown in Status; a publication that fails is
//! retried at the next one.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use agent::backoff::Backoff;

use crate::shared_state::{DEMO_SHARE_WINDOW, PublishedWeights, Shared};
use crate::storage::checkpoint;
use crate::storage::replay::Sample;
use crate::training::dqn::{Batch, Dqn};
use agent::config::RunConfig;
use agent::features::{RawScalars, push_network_inputs};
use agent::weights;

/// Turns sampled transitions into an update's batch (the frames are used as they are; the
/// network's other inputs come from each frame's raw scalars or vector reading).
#[must_use]
pub fn make_batch(cfg: &RunConfig, s: Sample) -> Batch {
    let n = cfg.vector_len();
    let inputs = |sc: &[RawScalars], vectors: &[f32]| -> Vec<f32> {
        let mut out = Vec::with_capacity(sc.len() * cfg.scalar_inputs());
        for (k, raw) in sc.iter().enumerate() {
            push_network_inputs(cfg, raw, &vectors[k * n..(k + 1) * n], &mut out);
        }
        out
    };
    Batch {
        scalars: inputs(&s.scalars, &s.vectors),
        next_scalars: inputs(&s.next_scalars, &s.next_vectors),
        images: s.images,
        next_images: s.next_images,
        actions: s.actions,
        rewards: s.rewards,
        discounts: s.discounts,
        weights: s.weights,
        demos: s.demos,
    }
}

/// The first checkpoint after training starts comes after at most this long.
pub const FIRST_CHECKPOINT: Duration = Duration::from_secs(30);

/// Publishes the online weights as a new version (from the run's version lease: newer than any
/// version published before, also by an earlier process of the run).
pub fn publish(shared: &Shared, dqn: &Dqn) -> anyhow::Result<u64> {
    let bytes = weights::to_safetensors(&dqn.online, "")?;
    let version = shared.versions.lock().expect("versions lock").next_version()?;
    *shared.weights.write().expect("weights lock") = PublishedWeights { version, bytes: Arc::new(bytes) };
    shared.counters.lock().expect("counters lock").weights_version = version;
    Ok(version)
}

/// Writes a checkpoint of the current state. With a replay log, the counters it saves include the
/// batches up to a log position, which is made durable first: a resumed learner counts the
/// batches after it from the log, and none twice.
pub fn save_checkpoint(shared: &Shared, dqn: &Dqn, run_dir: &std::path::Path) -> anyhow::Result<PathBuf> {
    let mut counters = shared.counters.lock().expect("counters lock").clone();
    counters.learner_step = dqn.updates;
    counters.elapsed_secs = shared.run_secs();
    if let Some(log) = &shared.log {
        log.wait_durable(counters.replay_log_position)?;
    }
    Ok(checkpoint::save(run_dir, dqn, &counters, &shared.cfg.to_toml())?)
}

/// When the next checkpoint is due, and how long to wait after a failed one.
#[derive(Debug)]
struct CheckpointSchedule {
    next: Instant,
    retry: Backoff,
}

impl CheckpointSchedule {
    /// 5 s doubling to 5 min, without jitter (one learner, no herd).
    const RETRY: Backoff = Backoff::new(Duration::from_secs(5), Duration::from_secs(300));

    /// Writes a checkpoint if one is due; a failure is logged, shown in Status and retried.
    fn tick(&mut self, shared: &Shared, dqn: &Dqn, run_dir: &std::path::Path, interval: Duration) {
        if Instant::now() < self.next {
            return;
        }
        match save_checkpoint(shared, dqn, run_dir) {
            Ok(path) => {
                tracing::info!(path = %path.display(), learner_step = dqn.updates, "checkpoint written");
                if shared.checkpoint_error.lock().expect("checkpoint error lock").take().is_some() {
                    tracing::info!("checkpoints work again");
                }
                self.next = Instant::now() + interval;
                self.retry.reset();
            }
            Err(e) => {
                let message = format!("{e:#}");
                let retry = self.retry.next_wait();
                tracing::error!(error = %message, retry_in_secs = retry.as_secs(), "writing a checkpoint failed; training goes on and the write is retried");
                *shared.checkpoint_error.lock().expect("checkpoint error lock") = Some(message);
                self.next = Instant::now() + retry;
            }
        }
    }
}

/// Runs until shutdown is requested; returns the agent for the final checkpoint.
pub fn run(shared: &Arc<Shared>, mut dqn: Dqn, run_dir: &std::path::Path) -> anyhow::Result<Dqn> {
    let a = shared.cfg.agent.clone();
    let interval = Duration::from_secs(shared.cfg.service.checkpoint_interval_secs.max(1));
    let mut checkpoints = CheckpointSchedule { next: Instant::now() + interval.min(FIRST_CHECKPOINT), retry: CheckpointSchedule::RETRY };
    // A resumed learner's rebuilt replay was trained on by its predecessor: the replay ratio
    // counts what arrives from now on.
    let stored_at_start = {
        let mut c = shared.counters.lock().expect("counters lock");
        c.learner_step = dqn.updates;
        c.transitions_stored
    };
    // Where the server set none (a caller that starts this loop itself), the count starts here.
    shared.ratio_session.lock().expect("ratio session lock").get_or_insert((stored_at_start, dqn.updates));
    let _clear = ClearBaselineOnExit(shared);
    let mut smoothed = Smoothed::default();
    pretrain(shared, &mut dqn, &mut smoothed, &mut checkpoints, run_dir, interval);
    while !shared.stopping() {
        checkpoints.tick(shared, &dqn, run_dir, interval);
        let (len, stored) = {
            let r = shared.replay.lock().expect("replay lock");
            let c = shared.counters.lock().expect("counters lock");
            (r.len(), c.transitions_stored)
        };
        if len < a.min_replay {
            wait_for_data(shared);
            continue;
        }
        // Count from the moment the replay first reached its minimum in this session (if a
        // stream storing a batch has not fixed it already).
        shared.fix_ratio_baseline(len, stored);
        if shared.updates_owed() == 0 {
            wait_for_data(shared);
            continue;
        }
        let share = shared.cfg.demo_share(shared.counters.lock().expect("counters lock").env_steps);
        let Some(sample) = shared.replay.lock().expect("replay lock").sample_mixed(a.batch_size, share) else { continue };
        train_on(shared, &mut dqn, sample, &mut smoothed);
        // The first held batch that the ratio allows goes through now, not at some later look.
        if shared.may_store_a_batch() {
            shared.backpressure.wake();
        }
        if dqn.updates.is_multiple_of(a.publish_every_updates)
            && let Err(e) = publish(shared, &dqn)
        {
            tracing::error!(error = %format!("{e:#}"), "publishing weights failed; retried at the next publication");
        }
    }
    Ok(dqn)
}

/// The smoothed measurements of the updates, for Status and the metrics.
#[derive(Debug, Default)]
struct Smoothed {
    loss: Option<f64>,
    mean_q: Option<f64>,
    margin_loss: Option<f64>,
    /// (demonstrations, samples) of the last batches.
    batches: std::collections::VecDeque<(usize, usize)>,
}

/// One update on `sample`: priorities, the smoothed measurements, the learner step.
fn train_on(shared: &Shared, dqn: &mut Dqn, sample: Sample, m: &mut Smoothed) {
    let prioritized = shared.cfg.agent.prioritized_replay;
    let slots = if prioritized { sample.slots.clone() } else { Vec::new() };
    let (demos, n) = (sample.demos, sample.actions.len());
    let stats = dqn.update(&make_batch(&shared.cfg, sample));
    if prioritized {
        shared.replay.lock().expect("replay lock").update_priorities(&slots, &stats.td_abs);
    }
    let smooth = |ema: Option<f64>, x: f32| Some(ema.map_or(f64::from(x), |e| 0.95 * e + 0.05 * f64::from(x)));
    m.loss = smooth(m.loss, stats.loss);
    m.mean_q = smooth(m.mean_q, stats.mean_q);
    if let Some(j) = stats.margin_loss {
        m.margin_loss = smooth(m.margin_loss, j);
    }
    if m.batches.len() == DEMO_SHARE_WINDOW {
        m.batches.pop_front();
    }
    m.batches.push_back((demos, n));
    {
        let (d, all) = m.batches.iter().fold((0, 0), |(d, all), &(x, y)| (d + x, all + y));
        let mut s = shared.stats.lock().expect("stats lock");
        s.loss = m.loss;
        s.mean_q = m.mean_q;
        s.margin_loss = m.margin_loss;
        s.demo_batch_share = if all == 0 { 0.0 } else { d as f64 / all as f64 };
    }
    shared.counters.lock().expect("counters lock").learner_step = dqn.updates;
}

/// DQfD's pre-training: `agent.demo_pretrain_updates` updates on demonstrations alone, once the
/// demonstration partition holds `min_replay` transitions (or is full), before the agent's
/// experience is trained on (a resumed run does those its checkpoint has not done). Its updates
/// are not the replay ratio's: they are added to the count the ratio starts from.
fn pretrain(
    shared: &Shared,
    dqn: &mut Dqn,
    m: &mut Smoothed,
    checkpoints: &mut CheckpointSchedule,
    run_dir: &std::path::Path,
    interval: Duration,
) {
    let a = &shared.cfg.agent;
    let ready = a.min_replay.min(a.demo_capacity);
    if dqn.updates < a.demo_pretrain_updates {
        tracing::info!(
            updates = a.demo_pretrain_updates - dqn.updates,
            demonstrations_needed = ready,
            "waiting for demonstrations to pre-train on (actor --demonstrate); the agent's experience is trained on after"
        );
    }
    let mut announced = false;
    while dqn.updates < a.demo_pretrain_updates && !shared.stopping() {
        checkpoints.tick(shared, dqn, run_dir, interval);
        if shared.replay.lock().expect("replay lock").demo_len() < ready.max(1) {
            wait_for_data(shared);
            continue;
        }
        if !std::mem::replace(&mut announced, true) {
            tracing::info!(updates = a.demo_pretrain_updates - dqn.updates, "pre-training on demonstrations");
        }
        let Some(sample) = shared.replay.lock().expect("replay lock").sample_demos(a.batch_size) else { continue };
        train_on(shared, dqn, sample, m);
        {
            let mut session = shared.ratio_session.lock().expect("ratio session lock");
            if let Some((_, updates)) = session.as_mut() {
                *updates += 1;
            }
            if let Some(b) = shared.ratio_baseline.lock().expect("ratio baseline lock").as_mut() {
                b.updates_at_start += 1;
            }
        }
        shared.stats.lock().expect("stats lock").pretrain_updates_left = a.demo_pretrain_updates - dqn.updates;
        if dqn.updates.is_multiple_of(a.publish_every_updates)
            && let Err(e) = publish(shared, dqn)
        {
            tracing::error!(error = %format!("{e:#}"), "publishing weights failed; retried at the next publication");
        }
        if dqn.updates == a.demo_pretrain_updates {
            tracing::info!(learner_step = dqn.updates, "pre-training on demonstrations done");
            if let Err(e) = publish(shared, dqn) {
                tracing::error!(error = %format!("{e:#}"), "publishing weights failed; retried at the next publication");
            }
        }
    }
}

/// Clears the replay ratio's baseline when the training thread ends, however it ends: nothing is
/// owed to a thread that is gone, so no experience stream waits for it.
struct ClearBaselineOnExit<'a>(&'a Shared);

impl Drop for ClearBaselineOnExit<'_> {
    fn drop(&mut self) {
        // The session first, as `Shared::fix_ratio_baseline` locks them; no `expect`: this
        // runs while a panic unwinds too.
        if let Ok(mut session) = self.0.ratio_session.lock() {
            *session = None;
            if let Ok(mut b) = self.0.ratio_baseline.lock() {
                *b = None;
            }
        }
        self.0.backpressure.wake();
    }
}

/// Waits (at most 50 ms) for transitions to arrive, counting the time as idle.
fn wait_for_data(shared: &Shared) {
    let started = Instant::now();
    let (lock, cv) = &shared.data_arrived;
    let guard = lock.lock().expect("wait lock");
    let _ = cv.wait_timeout(guard, Duration::from_millis(50)).expect("wait lock");
    shared.stats.lock().expect("stats lock").idle_secs += started.elapsed().as_secs_f64();
}
