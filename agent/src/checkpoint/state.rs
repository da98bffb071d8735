//! `state.json`: the learner's progress, saved with the networks.

use serde::{Deserialize, Serialize};

/// The learner's counters.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Counters {
    pub run_id: String,
    pub learner_step: u64,
    pub env_steps: u64,
    pub transitions_received: u64,
    pub transitions_stored: u64,
    pub transitions_rejected: u64,
    pub batches_rejected: u64,
    pub episodes: u64,
    pub weights_version: u64,
    pub elapsed_secs: f64,
    /// Position in the replay log of the last batch these counters include (0: none, or no log).
    /// On resume, batches after it are counted again from the log. Absent from older checkpoints.
    #[serde(default)]
    pub replay_log_position: u64,
    /// Demonstration transitions received and stored (`actor --demonstrate`): not in
    /// `env_steps` nor `transitions_*`, which count the agent's own experience. Absent from older
    /// checkpoints and from runs without demonstrations.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub demo_transitions_received: u64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub demo_transitions_stored: u64,
}

fn is_zero(x: &u64) -> bool {
    *x == 0
}

/// `state.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    pub version: u32,
    pub counters: Counters,
    /// Adam steps taken.
    pub adam_t: u64,
    /// Adam's learning rate when saved (for the record: a resumed run keeps the learning rate of
    /// the configuration it resumes with).
    pub learning_rate: f64,
    /// `counters.elapsed_secs` as IEEE-754 bits. serde_json writes the shortest decimal that
    /// round-trips, but its default parser (without the `float_roundtrip` feature) can land one
    /// ulp off, so the exact value travels as bits too; readers check the two agree.
    pub elapsed_secs_bits: u64,
}

/// How far training had got, as far as a `state.json` says (for reports; every field optional, so
/// that a partial or foreign file still reads).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Progress {
    pub learner_step: Option<u64>,
    pub env_steps: Option<u64>,
    pub episodes: Option<u64>,
}

impl Progress {
    /// The counters a `state.json` holds, or none of them if it does not parse.
    #[must_use]
    pub fn from_state_json(bytes: &[u8]) -> Self {
        let v: serde_json::Value = serde_json::from_slice(bytes).unwrap_or_default();
        let c = &v["counters"];
        Self { learner_step: c["learner_step"].as_u64(), env_steps: c["env_steps"].as_u64(), episodes: c["episodes"].as_u64() }
    }
}
