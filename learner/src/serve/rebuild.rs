//! Resuming with `service.durability = "ack"`: the replay rebuilt from the replay log, and the
//! batches logged after the checkpoint counted in.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;

use crate::storage::replay::Replay;
use crate::storage::replay_log::{OnDamage, ReplayLog, StepShape};
use agent::checkpoint::Counters;
use agent::config::RunConfig;

/// Opens the replay log of `run_dir`, rebuilding `replay` from it, and adds the batches logged
/// after the checkpoint (`counters.replay_log_position`) to `counters`.
pub(super) fn rebuild(
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
    let (log, found) = ReplayLog::open(
        run_dir,
        StepShape { frame_bytes, vector_len: cfg.vector_len() },
        cfg.service.replay_log_segment_bytes,
        checkpointed,
        on_damage,
        |position, record| {
            if record.demonstration {
                // Demonstrations go back to their partition; a run that keeps none now drops them.
                let stored = replay.add_demo_steps(record.actor, &record.steps) as u64;
                if position > checkpointed {
                    let steps = record.steps.iter().filter(|s| s.t > 0).count() as u64;
                    after.demo_transitions_received += steps;
                    after.demo_transitions_stored += stored;
                    after.replay_log_position = position;
                }
                return replay.log_frame_end();
            }
            let stored = replay.add_steps(record.actor, &record.steps) as u64;
            if position > checkpointed {
                let env_steps = record.steps.iter().filter(|s| s.t > 0).count() as u64;
                after.env_steps += env_steps;
                after.transitions_received += env_steps;
                after.transitions_stored += stored;
                after.episodes += u64::from(record.episodes);
                after.replay_log_position = position;
            }
            replay.log_frame_end()
        },
    )?;
    // No actor continues an earlier process's streams.
    replay.end_all_streams();
    counters.env_steps += after.env_steps;
    counters.transitions_received += after.transitions_received;
    counters.transitions_stored += after.transitions_stored;
    counters.episodes += after.episodes;
    counters.demo_transitions_received += after.demo_transitions_received;
    counters.demo_transitions_stored += after.demo_transitions_stored;
    counters.replay_log_position = counters.replay_log_position.max(after.replay_log_position).max(found.last_position);
    log.note_frames(replay.log_frame_end(), replay.log_first_live_frame());
    if found.records > 0 {
        tracing::info!(
            batches = found.records,
            segments = found.segments,
            replay_size = replay.len(),
            demonstrations = replay.demo_len(),
            batches_after_checkpoint = found.last_position.saturating_sub(checkpointed),
            secs = format!("{:.1}", started.elapsed().as_secs_f64()),
            "replay rebuilt from the replay log"
        );
    }
    Ok(log)
}
