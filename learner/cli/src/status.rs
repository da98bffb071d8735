//! `learner status`: asks a learner for its status and prints it, readable or as JSON (both from
//! `learner::telemetry::status_report::StatusReport`).

use std::path::Path;

use proto::v1 as pb;

use learner::serve::ADDR_FILE;
use learner::telemetry::status_report::{ActorReport, DemonstrationsReport, EpisodesReport, ReliabilityReport, StatusReport};

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
    StatusReport::from(s.clone()).to_json()
}

/// Prints the status readably.
pub fn print_table(s: &pb::StatusResponse) {
    print!("{}", table(&StatusReport::from(s.clone())));
}

/// The readable status. Destructured without `..`: a field added to the report is placed in the
/// table (or named `_` here, with the reason) before this compiles.
#[must_use]
pub fn table(report: &StatusReport) -> String {
    let StatusReport {
        run_id,
        variant,
        uptime_secs,
        run_secs,
        learner_step,
        env_steps,
        weights_version,
        transitions_received,
        transitions_stored,
        transitions_rejected,
        batches_rejected,
        replay_size,
        replay_capacity,
        replay_bytes,
        replay_bytes_per_transition,
        updates_per_sec,
        env_steps_per_sec,
        held_secs,
        loss,
        mean_q,
        epsilon,
        episodes: EpisodesReport { total, window, mean_return, completion_rate, collision_rate },
        demonstrations:
            DemonstrationsReport {
                received: demo_received,
                stored: demo_stored,
                replay_size: demo_size,
                replay_capacity: demo_capacity,
                batch_share: demo_batch_share,
                share: demo_share,
                margin_loss,
                pretrain_updates_left,
            },
        reliability:
            ReliabilityReport {
                durability,
                replay_log_bytes,
                replay_log_segments,
                replay_log_first_position,
                replay_log_durable_position,
                transitions_evicted,
                streams_refused_too_large,
                streams_refused_undecodable,
                training_error,
                checkpoint_error,
                recent_refusal,
            },
        actors,
    } = report;
    let mib = |bytes: u64| bytes as f64 / (1 << 20) as f64;
    let or_nan = |x: &Option<f64>| x.unwrap_or(f64::NAN);
    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line(format!("run {run_id} ({variant}), up {uptime_secs:.0} s, trained {run_secs:.0} s over its sessions"));
    line(format!(
        "learner step {learner_step}   env steps {env_steps}   weights version {weights_version}   updates/s {updates_per_sec:.2}   env steps/s {env_steps_per_sec:.0}   actors held {held_secs:.0} s (replay ratio)"
    ));
    line(format!("loss {:.4}   mean Q {:.3}   epsilon schedule at the run's step {epsilon:.3}", or_nan(loss), or_nan(mean_q)));
    line(format!(
        "replay {replay_size}/{replay_capacity} transitions, {:.1} MiB ({replay_bytes_per_transition:.0} bytes each)   received {transitions_received}   stored {transitions_stored}   rejected {transitions_rejected} ({batches_rejected} batches)",
        mib(*replay_bytes)
    ));
    line(format!(
        "durability {durability}   replay log {:.1} MiB in {replay_log_segments} segments, positions {replay_log_first_position}..{replay_log_durable_position} durable   evicted {transitions_evicted}   refused streams: {streams_refused_too_large} too large, {streams_refused_undecodable} undecodable",
        mib(*replay_log_bytes)
    ));
    if !training_error.is_empty() {
        line(format!("TRAINING STOPPED: {training_error}"));
    }
    if !recent_refusal.is_empty() {
        line(format!("batches refused (last 30 s): {recent_refusal}"));
    }
    if !checkpoint_error.is_empty() {
        line(format!("checkpoint failing (retried): {checkpoint_error}"));
    }
    line(format!(
        "episodes {total} — last {window}: mean return {mean_return:.2}, completed {:.0}%, collided {:.0}%",
        100.0 * completion_rate,
        100.0 * collision_rate
    ));
    if *demo_received > 0 || actors.iter().any(|a| !a.demonstrator.is_empty()) {
        line(format!(
            "demonstrations received {demo_received}   stored {demo_stored}   in replay {demo_size}/{demo_capacity}   share of the last batches {:.1}% (configured {:.1}%)   margin loss {:.4}   pre-training updates left {pretrain_updates_left}",
            100.0 * demo_batch_share,
            100.0 * demo_share,
            or_nan(margin_loss)
        ));
    }
    line(format!(
        "{:<34} {:<12} {:>5} {:>9} {:>10} {:>8} {:>7} {:>12} {:>8} {:>7} {:>7} {:>8} {:>7} {:>8}",
        "actor",
        "name",
        "index",
        "connected",
        "last seen",
        "weights",
        "lag",
        "transitions",
        "rejected",
        "streams",
        "regist.",
        "dropped",
        "epsilon",
        "held"
    ));
    for a in actors {
        let ActorReport {
            actor_id,
            name,
            actor_index,
            connected,
            last_seen_secs,
            weights_version,
            version_lag,
            transitions,
            rejected_batches,
            open_streams,
            registrations,
            dropped_steps,
            epsilon,
            held_secs,
            demonstrator,
        } = a;
        let role = if demonstrator.is_empty() { String::new() } else { format!("  demonstrator ({demonstrator})") };
        line(format!(
            "{actor_id:<34} {name:<12} {actor_index:>5} {connected:>9} {last_seen_secs:>9.1}s {weights_version:>8} {version_lag:>7} {transitions:>12} {rejected_batches:>8} {open_streams:>7} {registrations:>7} {dropped_steps:>8} {epsilon:>7.3} {held_secs:>7.0}s{role}"
        ));
    }
    out
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

    /// Every number of the wire message reaches the table: each field set to its own value.
    #[test]
    fn the_table_shows_every_field() {
        let actor = pb::ActorStatus {
            actor_id: "actor-id-7".into(),
            name: "west".into(),
            actor_index: 9101,
            last_seen_secs: 9102.0,
            weights_version: 9103,
            version_lag: 9104,
            transitions: 9105,
            rejected_batches: 9106,
            connected: true,
            open_streams: 9107,
            registrations: 9108,
            dropped_steps: 9109,
            epsilon: 0.125,
            held_secs: 9110.0,
            demonstrator: "model-based-avoid".into(),
        };
        let s = pb::StatusResponse {
            run_id: "run-x".into(),
            uptime_secs: 9001.0,
            learner_step: 9002,
            weights_version: 9003,
            transitions_received: 9004,
            transitions_stored: 9005,
            transitions_rejected: 9006,
            batches_rejected: 9007,
            replay_size: 9008,
            replay_capacity: 9009,
            replay_bytes: 9010 << 20,
            updates_per_sec: 9011.0,
            env_steps_per_sec: 9012.0,
            actors: vec![actor],
            episodes: Some(pb::EpisodeStats {
                window: 9013,
                mean_return: 9014.0,
                completion_rate: 0.25,
                collision_rate: 0.5,
                episodes_total: 9015,
            }),
            loss: 9016.0,
            mean_q: 9017.0,
            epsilon: 0.375,
            variant: "hybrid".into(),
            durability: "ack".into(),
            replay_log_bytes: 9018 << 20,
            replay_log_segments: 9019,
            replay_log_first_position: 9020,
            replay_log_durable_position: 9021,
            transitions_evicted: 9022,
            training_error: "boom".into(),
            checkpoint_error: "disk full".into(),
            streams_refused_too_large: 9023,
            streams_refused_undecodable: 9024,
            recent_refusal: "bad seq".into(),
            env_steps: 9025,
            run_secs: 9026.0,
            held_secs: 9027.0,
            demo_transitions_received: 9028,
            demo_transitions_stored: 9029,
            demo_replay_size: 9030,
            demo_replay_capacity: 9031,
            demo_batch_share: 0.0625,
            demo_share: 0.1875,
            margin_loss: 9032.0,
            demo_pretrain_updates_left: 9033,
        };
        let text = table(&StatusReport::from(s));
        for n in (9001..=9033).chain(9101..=9110) {
            assert!(text.contains(&n.to_string()), "{n} is missing from the table:\n{text}");
        }
        for t in [
            "run-x",
            "hybrid",
            "ack",
            "boom",
            "disk full",
            "bad seq",
            "actor-id-7",
            "west",
            "0.125",
            "0.375",
            "25%",
            "50%",
            "6.2%",
            "18.8%",
            "demonstrator (model-based-avoid)",
        ] {
            assert!(text.contains(t), "{t} is missing from the table:\n{text}");
        }
    }
}
