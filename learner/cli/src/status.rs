//! `learner status`: asks a learner for its status and prints it, readable or as JSON.

use std::path::Path;

use proto::v1 as pb;
use serde_json::json;

use learner::serve::ADDR_FILE;

/// The address a local run's learner listens on, read from `run_dir/server.addr`.
pub fn addr_from_run_dir(run_dir: &Path) -> anyhow::Result<String> {
    let path = run_dir.join(ADDR_FILE);
    match std::fs::read_to_string(&path) {
        Ok(text) if !text.trim().is_empty() => Ok(text.trim().to_owned()),
        Ok(_) => anyhow::bail!("{} is empty: expected the learner's address, host:port", path.display()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => anyhow::bail!(
            "{} does not exist: --run-dir must be the directory of a learner started on this machine \
             (`actor train --run-dir DIR` or `learner serve --run-dir DIR`); for another machine's learner give --addr HOST:PORT",
            path.display()
        ),
        Err(e) => Err(anyhow::Error::new(e).context(format!("reading {}", path.display()))),
    }
}

/// The status as a JSON value (the `--json` output).
#[must_use]
pub fn to_json(s: &pb::StatusResponse) -> serde_json::Value {
    let ep = s.episodes.unwrap_or_default();
    let finite = |x: f64| if x.is_finite() { json!(x) } else { serde_json::Value::Null };
    json!({
        "run_id": s.run_id,
        "variant": s.variant,
        "uptime_secs": s.uptime_secs,
        "learner_step": s.learner_step,
        "weights_version": s.weights_version,
        "transitions_received": s.transitions_received,
        "transitions_stored": s.transitions_stored,
        "transitions_rejected": s.transitions_rejected,
        "batches_rejected": s.batches_rejected,
        "replay_size": s.replay_size,
        "replay_capacity": s.replay_capacity,
        "replay_bytes": s.replay_bytes,
        "updates_per_sec": s.updates_per_sec,
        "env_steps_per_sec": s.env_steps_per_sec,
        "loss": finite(s.loss),
        "mean_q": finite(s.mean_q),
        "epsilon": s.epsilon,
        "episodes": {
            "total": ep.episodes_total,
            "window": ep.window,
            "mean_return": ep.mean_return,
            "completion_rate": ep.completion_rate,
            "collision_rate": ep.collision_rate,
        },
        "reliability": {
            "durability": s.durability,
            "replay_log_bytes": s.replay_log_bytes,
            "replay_log_segments": s.replay_log_segments,
            "replay_log_first_position": s.replay_log_first_position,
            "replay_log_durable_position": s.replay_log_durable_position,
            "transitions_evicted": s.transitions_evicted,
            "streams_refused_too_large": s.streams_refused_too_large,
            "streams_refused_undecodable": s.streams_refused_undecodable,
            "training_error": s.training_error,
            "checkpoint_error": s.checkpoint_error,
            "recent_refusal": s.recent_refusal,
        },
        "actors": s.actors.iter().map(|a| json!({
            "actor_id": a.actor_id,
            "name": a.name,
            "actor_index": a.actor_index,
            "connected": a.connected,
            "last_seen_secs": a.last_seen_secs,
            "weights_version": a.weights_version,
            "version_lag": a.version_lag,
            "transitions": a.transitions,
            "rejected_batches": a.rejected_batches,
            "open_streams": a.open_streams,
            "registrations": a.registrations,
            "dropped_steps": a.dropped_steps,
            "epsilon": a.epsilon,
        })).collect::<Vec<_>>(),
    })
}

/// Prints the status readably.
pub fn print_table(s: &pb::StatusResponse) {
    let ep = s.episodes.unwrap_or_default();
    println!("run {} ({}), up {:.0} s", s.run_id, s.variant, s.uptime_secs);
    println!(
        "learner step {}   weights version {}   updates/s {:.2}   env steps/s {:.0}",
        s.learner_step, s.weights_version, s.updates_per_sec, s.env_steps_per_sec
    );
    println!("loss {:.4}   mean Q {:.3}   epsilon schedule at the run's step {:.3}", s.loss, s.mean_q, s.epsilon);
    println!(
        "replay {}/{} transitions, {:.1} MiB   received {}   stored {}   rejected {} ({} batches)",
        s.replay_size,
        s.replay_capacity,
        s.replay_bytes as f64 / (1 << 20) as f64,
        s.transitions_received,
        s.transitions_stored,
        s.transitions_rejected,
        s.batches_rejected
    );
    println!(
        "durability {}   replay log {:.1} MiB in {} segments, durable to position {}   evicted {}   refused streams: {} too large, {} undecodable",
        s.durability,
        s.replay_log_bytes as f64 / (1 << 20) as f64,
        s.replay_log_segments,
        s.replay_log_durable_position,
        s.transitions_evicted,
        s.streams_refused_too_large,
        s.streams_refused_undecodable
    );
    if !s.training_error.is_empty() {
        println!("TRAINING STOPPED: {}", s.training_error);
    }
    if !s.recent_refusal.is_empty() {
        println!("batches refused (last 30 s): {}", s.recent_refusal);
    }
    if !s.checkpoint_error.is_empty() {
        println!("checkpoint failing (retried): {}", s.checkpoint_error);
    }
    println!(
        "episodes {} — last {}: mean return {:.2}, completed {:.0}%, collided {:.0}%",
        ep.episodes_total,
        ep.window,
        ep.mean_return,
        100.0 * ep.completion_rate,
        100.0 * ep.collision_rate
    );
    println!(
        "{:<34} {:<12} {:>5} {:>9} {:>10} {:>7} {:>12} {:>8} {:>7}",
        "actor", "name", "index", "connected", "last seen", "lag", "transitions", "rejected", "epsilon"
    );
    for a in &s.actors {
        println!(
            "{:<34} {:<12} {:>5} {:>9} {:>9.1}s {:>7} {:>12} {:>8} {:>7.3}",
            a.actor_id, a.name, a.actor_index, a.connected, a.last_seen_secs, a.version_lag, a.transitions, a.rejected_batches, a.epsilon
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_address_comes_from_server_addr_and_a_missing_file_is_explained() {
        let dir = tempfile::tempdir().unwrap();
        let e = addr_from_run_dir(dir.path()).unwrap_err().to_string();
        assert!(e.contains("server.addr does not exist") && e.contains("--addr"), "{e}");
        std::fs::write(dir.path().join(ADDR_FILE), "").unwrap();
        assert!(addr_from_run_dir(dir.path()).unwrap_err().to_string().contains("is empty"));
        std::fs::write(dir.path().join(ADDR_FILE), "127.0.0.1:41234\n").unwrap();
        assert_eq!(addr_from_run_dir(dir.path()).unwrap(), "127.0.0.1:41234");
    }
}
