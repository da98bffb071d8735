//! The learner's status as one type: the wire's `StatusResponse` read into [`StatusReport`], from
//! which `learner status --json` (serde), `learner status`'s table (`learner-cli`) and the
//! Prometheus metrics ([`EXPORTED`], read by JSON pointer from the same serialisation) derive.
//!
//! Every side is held to the type: [`StatusReport::from`] destructures the wire message without
//! `..` (a field added to the proto does not compile until it is placed here), the table
//! destructures the report the same way, and a test fails unless every number of the report is
//! either exported to Prometheus or listed in [`NOT_EXPORTED`] with the reason.

use prometheus_client::metrics::MetricType;
use proto::v1 as pb;
use serde::Serialize;

/// `learner status --json`: the run's state, grouped as it is printed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StatusReport {
    pub run_id: String,
    /// `hybrid` or `end_to_end`.
    pub variant: String,
    /// Seconds since this learner process started.
    pub uptime_secs: f64,
    /// Seconds the run has trained, over all its learner processes.
    pub run_secs: f64,
    /// DQN updates done.
    pub learner_step: u64,
    /// Environment steps the actors reported over the run.
    pub env_steps: u64,
    pub weights_version: u64,
    pub transitions_received: u64,
    pub transitions_stored: u64,
    pub transitions_rejected: u64,
    pub batches_rejected: u64,
    pub replay_size: u64,
    pub replay_capacity: u64,
    pub replay_bytes: u64,
    /// Replay bytes per stored transition (frames or vector readings, scalars and bookkeeping);
    /// 0 while the replay is empty.
    pub replay_bytes_per_transition: f64,
    pub updates_per_sec: f64,
    pub env_steps_per_sec: f64,
    /// Seconds experience streams waited for the training thread to catch up with the replay
    /// ratio, summed over streams.
    pub held_secs: f64,
    /// `null` before training (NaN on the wire).
    pub loss: Option<f64>,
    /// `null` before training (NaN on the wire).
    pub mean_q: Option<f64>,
    /// The ε schedule at the run's environment steps.
    pub epsilon: f64,
    pub episodes: EpisodesReport,
    pub demonstrations: DemonstrationsReport,
    pub reliability: ReliabilityReport,
    pub actors: Vec<ActorReport>,
}

/// Demonstrations (`actor --demonstrate`) and what training takes of them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemonstrationsReport {
    /// Demonstration transitions received and stored over the run.
    pub received: u64,
    pub stored: u64,
    /// Transitions in the demonstration partition now, and its capacity.
    pub replay_size: u64,
    pub replay_capacity: u64,
    /// The share of demonstrations in the last 100 training batches.
    pub batch_share: f64,
    /// The configured share now (`agent.demo_share`, decayed); 0 while there are none.
    pub share: f64,
    /// DQfD's large-margin loss (smoothed); `null` before a batch held a demonstration.
    pub margin_loss: Option<f64>,
    /// Pre-training updates still to do.
    pub pretrain_updates_left: u64,
}

/// The recent episodes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodesReport {
    /// Episodes finished over the run.
    pub total: u64,
    /// How many recent episodes the rates are over.
    pub window: u32,
    pub mean_return: f64,
    pub completion_rate: f64,
    pub collision_rate: f64,
}

/// Durability, refusals and training health.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReliabilityReport {
    /// `ack` or `none`.
    pub durability: String,
    pub replay_log_bytes: u64,
    pub replay_log_segments: u32,
    pub replay_log_first_position: u64,
    pub replay_log_durable_position: u64,
    pub transitions_evicted: u64,
    pub streams_refused_too_large: u64,
    pub streams_refused_undecodable: u64,
    /// Empty while training runs.
    pub training_error: String,
    /// Empty unless checkpoint writes are failing.
    pub checkpoint_error: String,
    /// Empty unless a batch was refused in the last 30 s.
    pub recent_refusal: String,
}

/// One actor, as the learner knows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ActorReport {
    pub actor_id: String,
    pub name: String,
    pub actor_index: u32,
    pub connected: bool,
    pub last_seen_secs: f64,
    pub weights_version: u64,
    pub version_lag: u64,
    pub transitions: u64,
    pub rejected_batches: u64,
    pub open_streams: u32,
    pub registrations: u64,
    pub dropped_steps: u64,
    pub epsilon: f32,
    /// Seconds its streams waited for the replay ratio (counted as each wait ends).
    pub held_secs: f64,
    /// The driver it demonstrates with; empty for a learning actor.
    pub demonstrator: String,
}

impl From<pb::StatusResponse> for StatusReport {
    fn from(s: pb::StatusResponse) -> Self {
        // No `..`: a field added to the wire message must be placed here before this compiles.
        let pb::StatusResponse {
            run_id,
            uptime_secs,
            learner_step,
            weights_version,
            transitions_received,
            transitions_stored,
            transitions_rejected,
            batches_rejected,
            replay_size,
            replay_capacity,
            replay_bytes,
            updates_per_sec,
            env_steps_per_sec,
            actors,
            episodes,
            loss,
            mean_q,
            epsilon,
            variant,
            durability,
            replay_log_bytes,
            replay_log_segments,
            replay_log_first_position,
            replay_log_durable_position,
            transitions_evicted,
            training_error,
            checkpoint_error,
            streams_refused_too_large,
            streams_refused_undecodable,
            recent_refusal,
            env_steps,
            run_secs,
            held_secs,
            demo_transitions_received,
            demo_transitions_stored,
            demo_replay_size,
            demo_replay_capacity,
            demo_batch_share,
            demo_share,
            margin_loss,
            demo_pretrain_updates_left,
        } = s;
        let pb::EpisodeStats { window, mean_return, completion_rate, collision_rate, episodes_total } = episodes.unwrap_or_default();
        let finite = |x: f64| x.is_finite().then_some(x);
        Self {
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
            replay_bytes_per_transition: if replay_size == 0 { 0.0 } else { replay_bytes as f64 / replay_size as f64 },
            updates_per_sec,
            env_steps_per_sec,
            held_secs,
            loss: finite(loss),
            mean_q: finite(mean_q),
            epsilon,
            episodes: EpisodesReport { total: episodes_total, window, mean_return, completion_rate, collision_rate },
            demonstrations: DemonstrationsReport {
                received: demo_transitions_received,
                stored: demo_transitions_stored,
                replay_size: demo_replay_size,
                replay_capacity: demo_replay_capacity,
                batch_share: demo_batch_share,
                share: demo_share,
                margin_loss: finite(margin_loss),
                pretrain_updates_left: demo_pretrain_updates_left,
            },
            reliability: ReliabilityReport {
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
            actors: actors.into_iter().map(ActorReport::from).collect(),
        }
    }
}

impl From<pb::ActorStatus> for ActorReport {
    fn from(a: pb::ActorStatus) -> Self {
        let pb::ActorStatus {
            actor_id,
            name,
            actor_index,
            last_seen_secs,
            weights_version,
            version_lag,
            transitions,
            rejected_batches,
            connected,
            open_streams,
            registrations,
            dropped_steps,
            epsilon,
            held_secs,
            demonstrator,
        } = a;
        Self {
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
        }
    }
}

impl StatusReport {
    /// The report as JSON (what `--json` prints and what the Prometheus metrics are read from).
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a status report is plain data")
    }
}

/// A field of the report exported to Prometheus under a name of its own (the names predate the
/// report and dashboards use them).
#[derive(Debug, Clone, Copy)]
pub struct Exported {
    /// The field, as a JSON pointer into [`StatusReport::to_json`] (into one actor's object for
    /// [`EXPORTED_PER_ACTOR`]).
    pub field: &'static str,
    pub name: &'static str,
    pub help: &'static str,
    /// `Counter` (the encoder adds `_total` to its name) or `Gauge`.
    pub kind: MetricType,
}

const fn counter(field: &'static str, name: &'static str, help: &'static str) -> Exported {
    Exported { field, name, help, kind: MetricType::Counter }
}

const fn gauge(field: &'static str, name: &'static str, help: &'static str) -> Exported {
    Exported { field, name, help, kind: MetricType::Gauge }
}

/// The run's metrics, in the order of the exposition.
pub const EXPORTED: &[Exported] = &[
    counter("/learner_step", "learner_updates", "DQN updates done."),
    counter("/env_steps", "learner_env_steps", "Environment steps received."),
    counter("/transitions_received", "learner_transitions_received", "Transitions received from actors."),
    counter("/transitions_stored", "learner_transitions_stored", "Transitions stored in replay."),
    counter("/transitions_rejected", "learner_transitions_rejected", "Transitions rejected as invalid."),
    counter("/batches_rejected", "learner_batches_rejected", "Batches rejected as invalid."),
    counter("/episodes/total", "learner_episodes", "Episodes finished by actors."),
    gauge("/weights_version", "learner_weights_version", "Version of the newest published weights."),
    gauge("/replay_size", "learner_replay_size", "Transitions in replay."),
    gauge("/replay_bytes", "learner_replay_bytes", "Bytes used by replay."),
    gauge("/updates_per_sec", "learner_updates_per_second", "DQN updates per second over the last 10 s."),
    gauge("/env_steps_per_sec", "learner_env_steps_per_second", "Environment steps per second over the last 10 s."),
    gauge("/loss", "learner_loss", "Recent mean Huber loss (NaN before training)."),
    gauge("/mean_q", "learner_mean_q", "Recent mean Q of the actions taken (NaN before training)."),
    gauge("/epsilon", "learner_epsilon", "Exploration rate of the schedule at the run's environment steps."),
    gauge("/episodes/mean_return", "learner_episode_return_mean", "Mean return of the recent episodes (service.stats_window)."),
    gauge("/episodes/completion_rate", "learner_episode_completion_rate", "Share of the recent episodes that reached their goal."),
    gauge("/episodes/collision_rate", "learner_episode_collision_rate", "Share of the recent episodes that ended in a collision."),
    gauge("/uptime_secs", "learner_uptime_seconds", "Seconds since this learner process started."),
    counter(
        "/held_secs",
        "learner_held_seconds",
        "Seconds experience streams waited for training to catch up with the replay ratio, summed over streams.",
    ),
    gauge("/run_secs", "learner_run_seconds", "Seconds the run has trained, over all its sessions."),
    counter("/demonstrations/received", "learner_demo_transitions_received", "Demonstration transitions received from demonstrators."),
    counter("/demonstrations/stored", "learner_demo_transitions_stored", "Demonstration transitions stored in their replay partition."),
    gauge("/demonstrations/replay_size", "learner_demo_replay_size", "Transitions in the replay's demonstration partition."),
    gauge("/demonstrations/batch_share", "learner_demo_batch_share", "Share of demonstrations in the last 100 training batches."),
    gauge("/demonstrations/margin_loss", "learner_margin_loss", "Recent large-margin loss on demonstrations (NaN before any)."),
];

/// Each connected actor's metrics, labelled `actor` with its name.
pub const EXPORTED_PER_ACTOR: &[Exported] = &[
    gauge("/version_lag", "learner_actor_weights_lag", "Versions an actor's weights are behind the newest (connected actors)."),
    gauge("/epsilon", "learner_actor_epsilon", "Exploration rate of an actor's last batch (connected actors)."),
];

/// The fields Prometheus does not get, and why (text, identities, and the configuration).
pub const NOT_EXPORTED: &[(&str, &str)] = &[
    ("/run_id", "text: the run is the scrape target's label"),
    ("/variant", "text"),
    ("/replay_capacity", "configuration, not a measurement"),
    ("/replay_bytes_per_transition", "learner_replay_bytes divided by learner_replay_size"),
    ("/episodes/window", "configuration (service.stats_window)"),
    ("/reliability/durability", "text"),
    ("/reliability/replay_log_bytes", "shown by `learner status`; no dashboard uses it"),
    ("/reliability/replay_log_segments", "shown by `learner status`; no dashboard uses it"),
    ("/reliability/replay_log_first_position", "a position, not a quantity"),
    ("/reliability/replay_log_durable_position", "a position, not a quantity"),
    ("/reliability/transitions_evicted", "shown by `learner status`; no dashboard uses it"),
    ("/reliability/streams_refused_too_large", "counted in learner_batches_rejected"),
    ("/reliability/streams_refused_undecodable", "counted in learner_batches_rejected"),
    ("/reliability/training_error", "text: health reports NOT_SERVING"),
    ("/reliability/checkpoint_error", "text"),
    ("/reliability/recent_refusal", "text"),
    ("/actors", "per actor: EXPORTED_PER_ACTOR and NOT_EXPORTED_PER_ACTOR"),
    ("/demonstrations/replay_capacity", "configuration, not a measurement"),
    ("/demonstrations/share", "configuration (agent.demo_share and its decay)"),
    ("/demonstrations/pretrain_updates_left", "shown by `learner status`; a phase, over once it reaches 0"),
];

/// An actor's fields Prometheus does not get, and why.
pub const NOT_EXPORTED_PER_ACTOR: &[(&str, &str)] = &[
    ("/actor_id", "an identity (the label is the name)"),
    ("/name", "the label"),
    ("/actor_index", "an identity"),
    ("/connected", "only connected actors are exported; learner_actors_connected counts them"),
    ("/last_seen_secs", "only connected actors are exported"),
    ("/weights_version", "learner_actor_weights_lag says it relative to the newest"),
    ("/transitions", "sums to learner_transitions_received"),
    ("/rejected_batches", "sums to learner_batches_rejected"),
    ("/open_streams", "shown by `learner status`"),
    ("/registrations", "shown by `learner status`"),
    ("/dropped_steps", "shown by `learner status`"),
    ("/held_secs", "shown by `learner status`; sums to learner_held_seconds"),
    ("/demonstrator", "text"),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// A report in which every field is set, with one connected actor.
    fn full() -> StatusReport {
        let actor = pb::ActorStatus { actor_id: "a".into(), name: "n".into(), connected: true, epsilon: 0.5, ..Default::default() };
        let wire = pb::StatusResponse {
            run_id: "r".into(),
            loss: 0.25,
            mean_q: 1.5,
            actors: vec![actor],
            episodes: Some(pb::EpisodeStats { episodes_total: 3, ..Default::default() }),
            ..Default::default()
        };
        StatusReport::from(wire)
    }

    /// The JSON pointers of every leaf under `value`, not descending into `/actors`.
    fn leaves(value: &serde_json::Value, at: &str, out: &mut Vec<String>) {
        match value {
            serde_json::Value::Object(map) if at != "/actors" => {
                for (k, v) in map {
                    leaves(v, &format!("{at}/{k}"), out);
                }
            }
            _ => out.push(at.to_owned()),
        }
    }

    fn check(value: &serde_json::Value, exported: &[Exported], not_exported: &[(&str, &str)]) {
        let mut fields = Vec::new();
        leaves(value, "", &mut fields);
        let named: Vec<&str> = exported.iter().map(|e| e.field).chain(not_exported.iter().map(|(f, _)| *f)).collect();
        for f in &fields {
            assert_eq!(
                named.iter().filter(|n| *n == f).count(),
                1,
                "the status field {f} must be exported to Prometheus or listed in NOT_EXPORTED with its reason, once"
            );
        }
        for n in &named {
            assert!(fields.iter().any(|f| f == n), "{n} names no field of the status report");
        }
        for e in exported {
            let v = value.pointer(e.field).unwrap();
            assert!(v.is_number() || v.is_null(), "{} ({}) is exported but not a number: {v}", e.field, e.name);
        }
    }

    #[test]
    fn every_field_is_exported_to_prometheus_or_says_why_not() {
        let json = full().to_json();
        check(&json, EXPORTED, NOT_EXPORTED);
        check(&json["actors"][0], EXPORTED_PER_ACTOR, NOT_EXPORTED_PER_ACTOR);
    }

    #[test]
    fn not_a_number_on_the_wire_is_null_in_json() {
        let r = StatusReport::from(pb::StatusResponse { loss: f64::NAN, mean_q: f64::INFINITY, ..Default::default() });
        let json = r.to_json();
        assert!(json["loss"].is_null() && json["mean_q"].is_null(), "{json}");
        assert_eq!(full().to_json()["loss"], 0.25);
        assert_eq!(full().to_json()["episodes"]["total"], 3);
    }
}
