//! The training thread: decoupled from ingestion, it trains as fast as the replay ratio allows
//! (samples trained per transition inserted), publishes weights every few updates and writes
//! checkpoints on an interval.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::checkpoint;
use crate::config::RunConfig;
use crate::dqn::{Batch, Dqn};
use crate::replay::{RawScalars, Sample, raw_scalars};
use crate::state::{PublishedWeights, Shared};
use sim_core::config::Variant;

/// The network's scalar inputs from an observation's raw scalars: speed/v0; d/d0 for the hybrid
/// agent; and its path features with `agent.path_features` — scaled so that typical values are
/// near 1.
#[must_use]
pub fn scalar_features(cfg: &RunConfig, raw: &RawScalars) -> Vec<f32> {
    let r = &cfg.env.reward;
    let [speed, d, lateral, near, far] = *raw;
    match cfg.env.variant {
        // Angles are in radians already; the lateral offset is scaled by a lane's width.
        Variant::Hybrid if cfg.agent.path_features => vec![speed / r.v0(), d / r.d0, lateral / LANE_WIDTH, near, far],
        Variant::Hybrid => vec![speed / r.v0(), d / r.d0],
        Variant::EndToEnd => vec![speed / r.v0()],
    }
}

/// Scale of the lateral path feature, metres.
const LANE_WIDTH: f32 = 3.5;

/// The raw scalars of an environment's current state, as the actor sends them.
#[must_use]
pub fn env_scalars(env: &sim_core::env::Env) -> RawScalars {
    raw_scalars(env.ego.speed, env.tracking.d, env.path_features())
}

/// Turns sampled transitions into an update's batch (the frames are used as they are).
#[must_use]
pub fn make_batch(cfg: &RunConfig, s: Sample) -> Batch {
    let scalars = |sc: &[RawScalars]| -> Vec<f32> { sc.iter().flat_map(|x| scalar_features(cfg, x)).collect() };
    Batch {
        scalars: scalars(&s.scalars),
        next_scalars: scalars(&s.next_scalars),
        images: s.images,
        next_images: s.next_images,
        actions: s.actions,
        rewards: s.rewards,
        discounts: s.discounts,
        weights: s.weights,
    }
}

/// Publishes the online weights as a new version.
pub fn publish(shared: &Shared, dqn: &Dqn) -> anyhow::Result<u64> {
    let bytes = dqn.online.to_safetensors("")?;
    let mut w = shared.weights.write().expect("weights lock");
    let version = w.version + 1;
    *w = PublishedWeights { version, bytes: Arc::new(bytes) };
    drop(w);
    shared.counters.lock().expect("counters lock").weights_version = version;
    Ok(version)
}

/// Writes a checkpoint of the current state.
pub fn save_checkpoint(shared: &Shared, dqn: &Dqn, run_dir: &std::path::Path) -> anyhow::Result<PathBuf> {
    let mut counters = shared.counters.lock().expect("counters lock").clone();
    counters.learner_step = dqn.updates;
    counters.elapsed_secs = shared.run_secs();
    Ok(checkpoint::save(run_dir, dqn, &counters, &shared.cfg.to_toml())?)
}

/// Runs until shutdown is requested; returns the agent for the final checkpoint.
pub fn run(shared: &Arc<Shared>, mut dqn: Dqn, run_dir: &std::path::Path) -> anyhow::Result<Dqn> {
    let a = shared.cfg.agent.clone();
    let interval = Duration::from_secs(shared.cfg.service.checkpoint_interval_secs.max(1));
    let mut last_checkpoint = Instant::now();
    let mut stored_at_fill: Option<u64> = None;
    let updates_at_start = dqn.updates;
    let mut loss_ema: Option<f64> = None;
    let mut q_ema: Option<f64> = None;
    while !shared.stopping() {
        let (len, stored) = {
            let r = shared.replay.lock().expect("replay lock");
            let c = shared.counters.lock().expect("counters lock");
            (r.len(), c.transitions_stored)
        };
        if len < a.min_replay {
            wait_for_data(shared);
            continue;
        }
        // Count from the moment the replay first reached its minimum in this session.
        let fill = *stored_at_fill.get_or_insert(stored.saturating_sub(len as u64));
        let allowed = ((stored - fill) as f64 * f64::from(a.replay_ratio) / a.batch_size as f64).floor() as u64;
        if dqn.updates - updates_at_start >= allowed {
            wait_for_data(shared);
            continue;
        }
        let Some(sample) = shared.replay.lock().expect("replay lock").sample(a.batch_size) else { continue };
        let slots = if a.prioritized_replay { sample.slots.clone() } else { Vec::new() };
        let stats = dqn.update(&make_batch(&shared.cfg, sample));
        if a.prioritized_replay {
            shared.replay.lock().expect("replay lock").update_priorities(&slots, &stats.td_abs);
        }
        let smooth = |ema: Option<f64>, x: f32| Some(ema.map_or(f64::from(x), |e| 0.95 * e + 0.05 * f64::from(x)));
        loss_ema = smooth(loss_ema, stats.loss);
        q_ema = smooth(q_ema, stats.mean_q);
        {
            let mut s = shared.stats.lock().expect("stats lock");
            s.loss = loss_ema;
            s.mean_q = q_ema;
        }
        shared.counters.lock().expect("counters lock").learner_step = dqn.updates;
        if dqn.updates.is_multiple_of(a.publish_every_updates) {
            publish(shared, &dqn)?;
        }
        if last_checkpoint.elapsed() >= interval {
            let path = save_checkpoint(shared, &dqn, run_dir)?;
            tracing::info!(path = %path.display(), learner_step = dqn.updates, "checkpoint written");
            last_checkpoint = Instant::now();
        }
    }
    Ok(dqn)
}

/// Waits (at most 50 ms) for transitions to arrive, counting the time as idle.
fn wait_for_data(shared: &Shared) {
    let started = Instant::now();
    let (lock, cv) = &shared.data_arrived;
    let guard = lock.lock().expect("wait lock");
    let _ = cv.wait_timeout(guard, Duration::from_millis(50)).expect("wait lock");
    shared.stats.lock().expect("stats lock").idle_secs += started.elapsed().as_secs_f64();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_features_follow_the_variant_and_the_path_switch() {
        let raw = raw_scalars(13.889, 4.0, [1.75, -0.2, 0.6]);
        let mut cfg = RunConfig::preset("paper").unwrap();
        let close = |got: Vec<f32>, want: &[f32]| {
            assert_eq!(got.len(), want.len(), "{got:?}");
            assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-4), "{got:?} vs {want:?}");
        };
        close(scalar_features(&cfg, &raw), &[1.0, 0.5]);
        cfg.agent.path_features = true;
        close(scalar_features(&cfg, &raw), &[1.0, 0.5, 0.5, -0.2, 0.6]);
        assert_eq!(scalar_features(&cfg, &raw).len(), cfg.scalar_inputs());
        let e2e = RunConfig::preset("end-to-end-tuned").unwrap();
        close(scalar_features(&e2e, &raw), &[1.0]);
    }
}
