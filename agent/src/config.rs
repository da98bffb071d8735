//! The run's configuration: one TOML file with `[env]` (the simulator, see `sim_core::config`),
//! `[agent]` (network, replay and training) and `[service]` (the gRPC server and the run
//! directory). Every field has a documented default; values are validated at load with errors that
//! name the field.
//!
//! A file may start from a named preset ([`crate::presets::PRESETS`]): `preset = "paper"` (or `"end-to-end"`) at
//! the top level takes every value from the preset, and whatever else the file sets overrides it,
//! table by table (`[env.camera] width = 32` changes only the width). Without `preset`, the
//! starting point is the built-in defaults. The effective configuration written to a run
//! directory keeps the `preset` line, for the record.
//!
//! Extensions beyond the paper are switches of `[agent]`, all off in the defaults and in both
//! presets: `double_dqn`, `prioritized_replay` (with `priority_alpha`, `priority_beta`), `n_step`
//! (1 = the paper's one-step targets), `path_features` (signed planner inputs for the hybrid agent)
//! and `per_actor_epsilon` (Ape-X exploration).

use std::path::Path;

use serde::{Deserialize, Serialize};
use sim_core::actions::ActionSet;
use sim_core::config::{EnvConfig, Variant};

use crate::shape::NetShape;

/// The whole configuration of a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunConfig {
    /// A named preset the file starts from (`paper`, `end-to-end`, `hybrid-tuned`,
    /// `end-to-end-tuned`, `hybrid-hazards`); the file's other values override it, table by table; without one, the
    /// built-in defaults.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// The simulated world: the environment every actor runs.
    pub env: EnvConfig,
    /// The DQN agent: network sizes, learning, replay, exploration.
    pub agent: AgentConfig,
    /// The learner service (`learner serve`; `actor train` sets listen and run_dir itself).
    pub service: ServiceConfig,
}

/// The DQN agent and its training.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AgentConfig {
    /// Discrete actions: `paper6` (the paper code's six, braking at 0.1), `paper12` (the seed
    /// code's earlier twelve), or a full-authority set of 5, 7 or 9 steering values × full
    /// throttle, coast, full brake: `full15`, `full21`, `full27`. The default is the paper code's six.
    pub action_set: ActionSet,
    /// Filters of each of the three convolution layers. The default is the paper's.
    pub conv_filters: usize,
    /// Units of each of the two hidden fully connected layers. The default is the paper's.
    pub hidden: usize,
    /// Arithmetic of the wide convolutions and, in training, fc1: `auto` (bf16 on AMX where the CPU
    /// has it, else f32), `f32`, or `bf16` (on AMX, else on AVX512-BF16, which loses to f32 on
    /// Intel's cores and wins on AMD Zen 4, docs/PERFORMANCE.md#bf16; refused without either).
    /// Results differ between f32 and bf16 (bf16 keeps 8 significant bits) and between the two bf16
    /// kernels (their sums run in other orders); each is bit-identical run to run.
    pub precision: crate::fastnet::Precision,
    /// Discount γ.
    pub gamma: f32,
    /// Adam learning rate.
    pub learning_rate: f64,
    /// Transitions per update.
    pub batch_size: usize,
    /// Replay capacity, transitions.
    pub replay_capacity: usize,
    /// Replay memory cap, bytes, frames included.
    pub replay_max_bytes: u64,
    /// Transitions stored before training starts.
    pub min_replay: usize,
    /// Samples trained per transition inserted. 0.25 trains one batch of 32 per 128 steps.
    pub replay_ratio: f32,
    /// Updates between target-network copies.
    pub target_update_period: u64,
    /// Target-network averaging (Polyak): after every update the target moves τ of the way to the
    /// online network, θ' ← θ' + τ(θ − θ'). 0 is no averaging: the target is copied every
    /// `target_update_period` updates, which then goes unused with τ > 0.
    pub target_tau: f32,
    /// Gradients are rescaled to at most this global L2 norm.
    pub grad_clip_norm: f32,
    /// Huber loss threshold δ.
    pub huber_delta: f32,
    /// Extension switch: double DQN targets, the online network choosing the next action and the
    /// target network valuing it (van Hasselt 2016). Off, the paper's plain DQN.
    pub double_dqn: bool,
    /// Extension switch: prioritized replay, sampling by TD error (Schaul 2016). Off, uniform
    /// sampling, the paper's.
    pub prioritized_replay: bool,
    /// Prioritization exponent α of prioritized replay.
    pub priority_alpha: f32,
    /// Importance-sampling exponent β of prioritized replay.
    pub priority_beta: f32,
    /// Extension switch: n-step returns, 1..=32. 1 is the paper's one-step targets.
    pub n_step: usize,
    /// Extension switch, hybrid agent only: the network also sees the planner's path as signed
    /// numbers (lateral offset, heading angles to the route near and 25 m ahead; sim-core's
    /// `Env::path_features`), not only the paper's unsigned d.
    pub path_features: bool,
    /// Exploration rate at the start of the decay. ε decays linearly from `epsilon_start` to
    /// `epsilon_end` over `epsilon_decay_steps` environment steps.
    pub epsilon_start: f32,
    /// Exploration rate at the end of the decay.
    pub epsilon_end: f32,
    /// Environment steps of the decay.
    pub epsilon_decay_steps: u64,
    /// Extension switch: per-actor ε (Ape-X: ε_i = ε^(1 + α·i/(N−1)), i the actor's index, N = `apex_actors`)
    /// instead of the schedule, with `apex_epsilon` and `apex_alpha`.
    pub per_actor_epsilon: bool,
    /// Ape-X base ε, with `per_actor_epsilon`.
    pub apex_epsilon: f32,
    /// Ape-X exponent α, with `per_actor_epsilon`.
    pub apex_alpha: f32,
    /// Ape-X actor count N the exponents are spread over, with `per_actor_epsilon`.
    pub apex_actors: u32,
    /// How actors explore: `epsilon` or `ez_greedy`. `epsilon` is ε-greedy (each step random
    /// with probability ε); `ez_greedy` is ε-z-greedy (Dabney et al. 2021: with probability ε a
    /// random action is started and held for n steps, n drawn from a zeta (power-law)
    /// distribution with exponent `ez_mu`, at most `ez_max_repeat`). ε is the same in both
    /// (schedule or per-actor).
    pub exploration: Exploration,
    /// Exponent μ of ε-z-greedy's duration distribution, P(n) ∝ n^−μ (> 1; Dabney et al.: 2).
    pub ez_mu: f32,
    /// Longest hold of ε-z-greedy, in steps (at least 1; 1 is ε-greedy).
    pub ez_max_repeat: u32,
    /// Transitions the replay keeps from demonstrators (`actor --demonstrate`), in a partition of
    /// their own: FIFO among themselves, never evicted by the agent's experience. Its byte cap is
    /// `replay_max_bytes` scaled by `demo_capacity / replay_capacity`. 0 refuses demonstrators.
    pub demo_capacity: usize,
    /// Share of every training batch drawn from the demonstrations while there are any (each
    /// sample is one with this probability). Decays linearly to `demo_share_final` over
    /// `demo_share_decay_steps` environment steps.
    pub demo_share: f32,
    /// Share of demonstrations at the end of the decay.
    pub demo_share_final: f32,
    /// Environment steps of the decay; 0 keeps `demo_share` for the whole run.
    pub demo_share_decay_steps: u64,
    /// DQfD's margin l: the large-margin loss max_a [Q(s,a) + l·(a ≠ a_E)] − Q(s,a_E) asks the
    /// demonstrated action a_E to be worth at least this much more than any other.
    pub demo_margin: f32,
    /// Weight λ of the large-margin loss on demonstration samples, added to the TD loss (batch
    /// mean); 0 turns it off.
    pub demo_margin_weight: f32,
    /// Updates on demonstrations alone before the agent's experience is trained on (DQfD's
    /// pre-training); they start once the demonstration partition holds `min_replay` transitions
    /// (or is full). `actor train` starts its learning actors after them.
    pub demo_pretrain_updates: u64,
    /// Updates between weight publications to actors.
    pub publish_every_updates: u64,
    /// Seed of network initialisation and replay sampling.
    pub seed: u64,
}

impl Default for AgentConfig {
    fn default() -> Self {
        Self {
            action_set: ActionSet::Paper6,
            conv_filters: 64,
            hidden: 256,
            precision: crate::fastnet::Precision::Auto,
            gamma: 0.99,
            learning_rate: 2.5e-4,
            batch_size: 32,
            replay_capacity: 100_000,
            replay_max_bytes: 2 << 30,
            min_replay: 1_000,
            replay_ratio: 0.25,
            target_update_period: 1_000,
            target_tau: 0.0,
            grad_clip_norm: 10.0,
            huber_delta: 1.0,
            double_dqn: false,
            prioritized_replay: false,
            priority_alpha: 0.6,
            priority_beta: 0.4,
            n_step: 1,
            path_features: false,
            epsilon_start: 1.0,
            epsilon_end: 0.05,
            epsilon_decay_steps: 200_000,
            per_actor_epsilon: false,
            apex_epsilon: 0.4,
            apex_alpha: 7.0,
            apex_actors: 8,
            exploration: Exploration::Epsilon,
            ez_mu: 2.0,
            ez_max_repeat: 30,
            demo_capacity: 100_000,
            demo_share: 0.25,
            demo_share_final: 0.0,
            demo_share_decay_steps: 0,
            demo_margin: 0.8,
            demo_margin_weight: 1.0,
            demo_pretrain_updates: 0,
            publish_every_updates: 10,
            seed: 0,
        }
    }
}

/// The server and its run directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ServiceConfig {
    /// gRPC listen address.
    pub listen: String,
    /// Run directory: effective config, checkpoints, metrics.
    pub run_dir: String,
    /// Seconds between checkpoints. A fresh run writes one before it serves, and the first after
    /// training starts comes after at most 30 s; a failed write is retried with backoff.
    pub checkpoint_interval_secs: u64,
    /// Largest gRPC message accepted or sent, bytes. A weights message is ~7 MB for the paper
    /// network, a batch of 256 84×84 RGB transitions ~5.4 MB.
    pub max_message_bytes: usize,
    /// An actor counts as connected while an experience stream of it is open and it was heard from
    /// (a batch, or its weights poll every second) within this many seconds.
    pub actor_timeout_secs: u64,
    /// Episodes in the rolling statistics of the status.
    pub stats_window: usize,
    /// The most DQN updates the learner may owe the replay ratio before its experience streams stop
    /// taking batches until it catches up. The ratio holds on a machine where the learner is slower
    /// than the actors. 0 turns the hold off (the ratio is then a ceiling that a slow learner falls
    /// below).
    pub update_lag_limit: u64,
    /// `ack`: a batch is acknowledged only once it is in the replay log on disk
    /// (`RUN_DIR/replay-log/`, synced by group commit), and `--resume` rebuilds the replay from it.
    /// `none`: acknowledged once in memory; the replay starts empty after a restart.
    pub durability: Durability,
    /// Bytes per replay log segment. Segments whose transitions have all left the replay are
    /// deleted, so the log holds about the replay's bytes plus one segment.
    pub replay_log_segment_bytes: u64,
    /// PEM certificate the learner serves TLS with, gRPC and metrics, with `tls_key`; empty serves
    /// plaintext. Re-read on SIGHUP and when it changes (`--tls-cert`).
    pub tls_cert: String,
    /// PEM private key of `tls_cert` (`--tls-key`).
    pub tls_key: String,
    /// PEM CA certificate(s) clients' certificates must chain to: mutual TLS; empty: clients need
    /// no certificate. Needs `tls_cert` (`--tls-client-ca`).
    pub tls_client_ca: String,
}

/// How actors explore (`agent.exploration`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Exploration {
    /// ε-greedy: every step is random with probability ε.
    #[default]
    Epsilon,
    /// ε-z-greedy: with probability ε a random action held for a zeta-distributed duration.
    EzGreedy,
}

/// What an acknowledgement promises (`service.durability`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Durability {
    /// Acknowledged ⇒ on disk (the replay log, fsynced).
    #[default]
    Ack,
    /// Acknowledged ⇒ in memory only.
    None,
}

impl Durability {
    /// The configuration's spelling.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Ack => "ack",
            Self::None => "none",
        }
    }
}

impl Default for ServiceConfig {
    fn default() -> Self {
        Self {
            listen: "127.0.0.1:50051".into(),
            run_dir: "runs/default".into(),
            checkpoint_interval_secs: 300,
            max_message_bytes: 64 << 20,
            actor_timeout_secs: 10,
            stats_window: 100,
            update_lag_limit: 4,
            durability: Durability::Ack,
            replay_log_segment_bytes: 64 << 20,
            tls_cert: String::new(),
            tls_key: String::new(),
            tls_client_ca: String::new(),
        }
    }
}

/// A configuration that could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("reading config file {path}: {source}")]
    Read { path: String, source: std::io::Error },
    #[error("config file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("config file {path}: field `{field}`: {message}")]
    Invalid { path: String, field: String, message: String },
}

impl RunConfig {
    /// Loads and validates a TOML file; missing fields take their defaults.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read { path: shown.clone(), source })?;
        Self::from_toml(&text, &shown)
    }

    /// Parses and validates TOML text; `origin` names it in errors. With a `preset` key, the
    /// preset's values are the starting point and the text's other values override them.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let parse_error = |e: toml::de::Error| ConfigError::Parse { path: origin.into(), message: e.to_string() };
        let invalid = |(field, message): (String, String)| ConfigError::Invalid { path: origin.into(), field, message };
        // Parsed alone first, so that unknown fields and wrong types are reported with their line.
        let own: Self = toml::from_str(text).map_err(parse_error)?;
        let table = toml::from_str::<toml::Table>(text).map_err(parse_error)?;
        let (mut cfg, table) = match &own.preset {
            None => (own, table),
            Some(name) => {
                let base = Self::preset(name).map_err(|m| invalid(("preset".into(), m)))?;
                let mut merged = toml::Table::try_from(&base).expect("a configuration converts to a TOML table");
                merge_tables(&mut merged, table);
                (merged.clone().try_into().map_err(parse_error)?, merged)
            }
        };
        camera_as_written(&mut cfg.env, table.get("env").and_then(toml::Value::as_table));
        cfg.validate().map_err(invalid)?;
        Ok(cfg)
    }

    /// The configuration as TOML (what is written to the run directory).
    #[must_use]
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("the config serialises")
    }

    /// Checks every field; the error is (dotted field path, what is wrong).
    pub fn validate(&self) -> Result<(), (String, String)> {
        if let Some(name) = &self.preset {
            Self::preset(name).map_err(|m| ("preset".to_owned(), m))?;
        }
        self.env.validate().map_err(|e| (format!("env.{}", e.field), e.message))?;
        let a = &self.agent;
        let bad = |field: &str, message: String| Err((format!("agent.{field}"), message));
        if !(1..=4096).contains(&a.conv_filters) {
            return bad("conv_filters", format!("{} must be 1..=4096", a.conv_filters));
        }
        if !(1..=65536).contains(&a.hidden) {
            return bad("hidden", format!("{} must be 1..=65536", a.hidden));
        }
        if !(a.gamma > 0.0 && a.gamma <= 1.0) {
            return bad("gamma", format!("{} must be in (0, 1]", a.gamma));
        }
        if !(a.learning_rate.is_finite() && a.learning_rate > 0.0 && a.learning_rate < 1.0) {
            return bad("learning_rate", format!("{} must be in (0, 1)", a.learning_rate));
        }
        if !(1..=4096).contains(&a.batch_size) {
            return bad("batch_size", format!("{} must be 1..=4096", a.batch_size));
        }
        if a.replay_capacity < a.batch_size {
            return bad("replay_capacity", format!("{} must be at least batch_size ({})", a.replay_capacity, a.batch_size));
        }
        if a.min_replay < a.batch_size || a.min_replay > a.replay_capacity {
            return bad(
                "min_replay",
                format!("{} must be between batch_size ({}) and replay_capacity ({})", a.min_replay, a.batch_size, a.replay_capacity),
            );
        }
        if a.path_features && self.env.variant != Variant::Hybrid {
            return bad("path_features", "needs env.variant = \"hybrid\": the end-to-end agent has no planner input".to_owned());
        }
        if a.replay_max_bytes < 1 << 20 {
            return bad("replay_max_bytes", format!("{} is below 1 MiB", a.replay_max_bytes));
        }
        if !(a.replay_ratio.is_finite() && a.replay_ratio > 0.0 && a.replay_ratio <= 64.0) {
            return bad("replay_ratio", format!("{} must be in (0, 64]", a.replay_ratio));
        }
        if a.target_update_period == 0 {
            return bad("target_update_period", "must be at least 1".into());
        }
        if !(a.target_tau.is_finite() && (0.0..=1.0).contains(&a.target_tau)) {
            return bad("target_tau", format!("{} must be in [0, 1] (0: copy every target_update_period updates)", a.target_tau));
        }
        if !(a.grad_clip_norm.is_finite() && a.grad_clip_norm > 0.0) {
            return bad("grad_clip_norm", format!("{} must be > 0", a.grad_clip_norm));
        }
        if !(a.huber_delta.is_finite() && a.huber_delta > 0.0) {
            return bad("huber_delta", format!("{} must be > 0", a.huber_delta));
        }
        if !(1..=32).contains(&a.n_step) {
            return bad("n_step", format!("{} must be 1..=32", a.n_step));
        }
        for (x, f) in [
            (a.priority_alpha, "priority_alpha"),
            (a.priority_beta, "priority_beta"),
            (a.epsilon_start, "epsilon_start"),
            (a.epsilon_end, "epsilon_end"),
            (a.apex_epsilon, "apex_epsilon"),
        ] {
            if !(0.0..=1.0).contains(&x) {
                return bad(f, format!("{x} must be in [0, 1]"));
            }
        }
        if !(a.apex_alpha.is_finite() && a.apex_alpha >= 0.0) {
            return bad("apex_alpha", format!("{} must be >= 0", a.apex_alpha));
        }
        if a.apex_actors == 0 {
            return bad("apex_actors", "must be at least 1".into());
        }
        for (x, f) in [(a.demo_share, "demo_share"), (a.demo_share_final, "demo_share_final")] {
            if !(0.0..=1.0).contains(&x) {
                return bad(f, format!("{x} must be in [0, 1]"));
            }
        }
        if !(a.ez_mu.is_finite() && a.ez_mu > 1.0) {
            return bad("ez_mu", format!("{} must be > 1 (a zeta distribution's exponent)", a.ez_mu));
        }
        if !(1..=10_000).contains(&a.ez_max_repeat) {
            return bad("ez_max_repeat", format!("{} must be 1..=10000", a.ez_max_repeat));
        }
        if a.demo_capacity != 0 && a.demo_capacity < a.batch_size {
            return bad(
                "demo_capacity",
                format!("{} must be 0 (no demonstrations) or at least batch_size ({})", a.demo_capacity, a.batch_size),
            );
        }
        if !(a.demo_margin.is_finite() && a.demo_margin >= 0.0) {
            return bad("demo_margin", format!("{} must be >= 0", a.demo_margin));
        }
        if !(a.demo_margin_weight.is_finite() && a.demo_margin_weight >= 0.0) {
            return bad("demo_margin_weight", format!("{} must be >= 0 (0 turns the margin loss off)", a.demo_margin_weight));
        }
        if a.publish_every_updates == 0 {
            return bad("publish_every_updates", "must be at least 1".into());
        }
        let s = &self.service;
        if s.listen.trim().is_empty() {
            return Err(("service.listen".into(), "must be an address such as 127.0.0.1:50051".into()));
        }
        if s.run_dir.trim().is_empty() {
            return Err(("service.run_dir".into(), "must be a directory path".into()));
        }
        if s.max_message_bytes < 1 << 20 {
            return Err(("service.max_message_bytes".into(), format!("{} is below 1 MiB", s.max_message_bytes)));
        }
        if s.actor_timeout_secs == 0 {
            return Err(("service.actor_timeout_secs".into(), "must be at least 1".into()));
        }
        if s.replay_log_segment_bytes < 64 << 10 {
            return Err(("service.replay_log_segment_bytes".into(), format!("{} is below 64 KiB", s.replay_log_segment_bytes)));
        }
        if s.stats_window == 0 {
            return Err(("service.stats_window".into(), "must be at least 1".into()));
        }
        if s.tls_cert.is_empty() != s.tls_key.is_empty() {
            let missing = if s.tls_cert.is_empty() { "service.tls_cert" } else { "service.tls_key" };
            return Err((missing.into(), "TLS needs both tls_cert and tls_key (--tls-cert and --tls-key)".into()));
        }
        if !s.tls_client_ca.is_empty() && s.tls_cert.is_empty() {
            return Err(("service.tls_client_ca".into(), "mutual TLS needs the server's own tls_cert and tls_key too".into()));
        }
        if self.env.camera.is_none() && self.env.vector.is_none() {
            return Err((
                "env.camera".into(),
                "the agent needs something to see: configure a camera ([env.camera]), the vector sensor ([env.vector]) or both".into(),
            ));
        }
        Ok(())
    }

    /// The exploration rate of actor `index`: Ape-X's per-actor ε when configured, else the
    /// linear schedule after `env_steps` steps.
    #[must_use]
    pub fn epsilon(&self, index: u32, env_steps: u64) -> f32 {
        let a = &self.agent;
        if a.per_actor_epsilon {
            let n = a.apex_actors.max(2) - 1;
            a.apex_epsilon.powf(1.0 + a.apex_alpha * (index.min(n)) as f32 / n as f32)
        } else {
            let frac = (env_steps as f32 / a.epsilon_decay_steps.max(1) as f32).min(1.0);
            a.epsilon_start + (a.epsilon_end - a.epsilon_start) * frac
        }
    }

    /// The share of each batch drawn from demonstrations after `env_steps` environment steps:
    /// `demo_share` decayed linearly to `demo_share_final` over `demo_share_decay_steps`.
    #[must_use]
    pub fn demo_share(&self, env_steps: u64) -> f32 {
        let a = &self.agent;
        if a.demo_share_decay_steps == 0 {
            return a.demo_share;
        }
        let frac = (env_steps as f32 / a.demo_share_decay_steps as f32).min(1.0);
        a.demo_share + (a.demo_share_final - a.demo_share) * frac
    }

    /// The network this configuration describes (its camera, scalar inputs, actions, filters
    /// and hidden units). Without a camera it has no image and is a multilayer perceptron over the
    /// vector sensor's reading (`NetShape`).
    #[must_use]
    pub fn net_shape(&self) -> NetShape {
        let (height, width, channels) =
            self.env.camera.as_ref().map_or((0, 0, 0), |cam| (cam.height as usize, cam.width as usize, cam.stacked_channels()));
        NetShape {
            height,
            width,
            channels,
            scalars: self.scalar_inputs(),
            actions: self.agent.action_set.actions().len(),
            filters: self.agent.conv_filters,
            hidden: self.agent.hidden,
        }
    }

    /// Bytes of one camera frame as an actor sends it and the replay stores it (`H × W × C`; 0
    /// without a camera); the network's input holds `[env.camera] stack` of them.
    #[must_use]
    pub fn frame_bytes(&self) -> usize {
        self.env.camera.as_ref().map_or(0, |cam| cam.width as usize * cam.height as usize * usize::from(cam.channels()))
    }

    /// Values of one vector sensor reading (`[env.vector]`; 0 without it).
    #[must_use]
    pub fn vector_len(&self) -> usize {
        self.env.vector.as_ref().map_or(0, |v| v.len(self.env.variant))
    }

    /// The vector sensor's layout in words (`sim_core::sensor::VectorConfig::describe`), or
    /// `None` without it.
    #[must_use]
    pub fn vector_layout(&self) -> Option<String> {
        self.env.vector.as_ref().map(|v| v.describe(self.env.variant))
    }

    /// Refuses to load the weights of a checkpoint trained with `saved` into this run when the
    /// two disagree on what the network's outputs mean or what its input holds: the action set
    /// and the camera's frame stack. The error names both values and the field.
    pub fn check_checkpoint_body(&self, saved: &RunConfig) -> Result<(), String> {
        let (ours, theirs) = (self.agent.action_set, saved.agent.action_set);
        if ours != theirs {
            return Err(format!(
                "agent.action_set: the checkpoint was trained with `{}` ({} actions), this run is configured with `{}` ({} actions); \
                 its Q-values mean other actions: set action_set = \"{}\" or start a new run",
                theirs.name(),
                theirs.actions().len(),
                ours.name(),
                ours.actions().len(),
                theirs.name()
            ));
        }
        let (ours, theirs) = (self.vector_layout(), saved.vector_layout());
        if ours != theirs {
            let say = |l: &Option<String>| l.clone().map_or_else(|| "no vector sensor".to_owned(), |l| format!("`{l}`"));
            return Err(format!(
                "env.vector: the checkpoint sees {}, this run is configured with {}: configure the checkpoint's [env.vector] or start a new run",
                say(&theirs),
                say(&ours)
            ));
        }
        let (ours, theirs) =
            (self.env.camera.as_ref().map(|c| (c.width, c.height, c.rgb)), saved.env.camera.as_ref().map(|c| (c.width, c.height, c.rgb)));
        if ours.is_some() != theirs.is_some() {
            let say = |c: Option<(u32, u32, bool)>| c.map_or_else(|| "no camera".to_owned(), |(w, h, _)| format!("a {w}x{h} camera"));
            return Err(format!(
                "env.camera: the checkpoint sees {}, this run is configured with {}: configure the checkpoint's [env.camera] or start a new run",
                say(theirs),
                say(ours)
            ));
        }
        let stack = |c: &RunConfig| c.env.camera.as_ref().map_or(1, |cam| cam.stack);
        if stack(self) != stack(saved) {
            return Err(format!(
                "env.camera.stack: the checkpoint sees {} frame(s), this run is configured with {}: set stack = {} or start a new run",
                stack(saved),
                stack(self),
                stack(saved)
            ));
        }
        Ok(())
    }

    /// Bytes per pixel of one camera frame (1 gray, 3 RGB; 1 without a camera, whose frames are
    /// empty).
    #[must_use]
    pub fn frame_channels(&self) -> usize {
        self.env.camera.as_ref().map_or(1, |cam| usize::from(cam.channels()))
    }

    /// Frames the network sees at once (`[env.camera] stack`; 1 without a camera).
    #[must_use]
    pub fn frame_stack(&self) -> usize {
        self.env.camera.as_ref().map_or(1, |cam| cam.stack as usize)
    }

    /// A run small enough to train in seconds, for tests and smoke runs: a 16×16 gray camera,
    /// 2 filters and 8 hidden units, training after 32 transitions in batches of 8, weights
    /// published every 2 updates, a free loopback port and hourly checkpoints.
    #[must_use]
    pub fn tiny(run_dir: &Path) -> Self {
        let mut cfg = Self::default();
        cfg.env.camera = Some(sim_core::camera::CameraConfig { width: 16, height: 16, ..Default::default() });
        let a = &mut cfg.agent;
        (a.conv_filters, a.hidden, a.batch_size, a.min_replay, a.replay_capacity) = (2, 8, 8, 32, 1000);
        (a.replay_ratio, a.publish_every_updates) = (1.0, 2);
        cfg.service.listen = "127.0.0.1:0".into();
        cfg.service.run_dir = run_dir.display().to_string();
        cfg.service.checkpoint_interval_secs = 3600;
        cfg
    }

    /// Inputs of the network besides the image: with the vector sensor, its reading (which holds
    /// speed, d and the path itself); otherwise speed, d for the hybrid agent, and its path
    /// features with `agent.path_features` (`features::network_inputs`).
    #[must_use]
    pub fn scalar_inputs(&self) -> usize {
        if self.env.vector.is_some() {
            return self.vector_len();
        }
        match self.env.variant {
            Variant::Hybrid if self.agent.path_features => 2 + sim_core::env::PATH_FEATURES,
            Variant::Hybrid => 2,
            Variant::EndToEnd => 1,
        }
    }
}

/// Overlays `top` on `base`: tables merge key by key, any other value replaces.
/// `[env]` as TOML text (what the learner sends its actors) read as [`RunConfig::from_toml`]
/// reads it: with the vector sensor and no `camera` table, no camera.
pub fn env_from_toml(text: &str) -> Result<EnvConfig, toml::de::Error> {
    let mut env: EnvConfig = toml::from_str(text)?;
    camera_as_written(&mut env, Some(&toml::from_str::<toml::Table>(text)?));
    Ok(env)
}

/// With the vector sensor, an `[env]` without a `camera` table has no camera (as a configuration
/// without one is written); `EnvConfig`'s default camera is for files without the sensor, which
/// need one.
fn camera_as_written(env: &mut EnvConfig, table: Option<&toml::Table>) {
    if env.vector.is_some() && !table.is_some_and(|t| t.contains_key("camera")) {
        env.camera = None;
    }
}

fn merge_tables(base: &mut toml::Table, top: toml::Table) {
    for (key, value) in top {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => merge_tables(b, t),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_round_trip_through_toml() {
        let cfg = RunConfig::default();
        cfg.validate().unwrap();
        let back = RunConfig::from_toml(&cfg.to_toml(), "roundtrip").unwrap();
        assert_eq!(back, cfg);
    }

    #[test]
    fn a_configuration_without_a_camera_reads_back_without_one() {
        for name in ["hybrid-vector", "e2e-vector"] {
            let cfg = RunConfig::preset(name).unwrap();
            assert_eq!(RunConfig::from_toml(&cfg.to_toml(), "roundtrip").unwrap(), cfg, "{name}");
            let text = format!("preset = \"{name}\"\n[env.vector]\nobjects = 4\n[agent]\nhidden = 16\n");
            let tiny = RunConfig::from_toml(&text, "tiny.toml").unwrap();
            assert!(tiny.env.camera.is_none() && tiny.net_shape().channels == 0, "{name}: {tiny:?}");
            assert_eq!(RunConfig::from_toml(&tiny.to_toml(), "back").unwrap(), tiny, "{name}");
        }
        // A camera asked for beside the sensor is kept; without the sensor the default camera stays.
        let both = RunConfig::from_toml("preset = \"hybrid-vector\"\n[env.camera]\nwidth = 32\n", "both.toml").unwrap();
        assert_eq!(both.env.camera.as_ref().map(|c| c.width), Some(32));
        let with_vector = RunConfig::from_toml("preset = \"hybrid-tuned\"\n[env.vector]\nrays = 8\n", "tuned.toml").unwrap();
        assert!(with_vector.env.camera.is_some() && with_vector.env.vector.is_some());
        assert!(RunConfig::from_toml("[agent]\nhidden = 16\n", "plain.toml").unwrap().env.camera.is_some());
        // The [env] table the learner sends its actors reads back the same.
        let cfg = RunConfig::preset("hybrid-vector").unwrap();
        assert_eq!(env_from_toml(&toml::to_string(&cfg.env).unwrap()).unwrap(), cfg.env);
        let tuned = RunConfig::preset("hybrid-tuned").unwrap();
        assert_eq!(env_from_toml(&toml::to_string(&tuned.env).unwrap()).unwrap(), tuned.env);
    }

    #[test]
    fn partial_files_take_defaults() {
        let cfg = RunConfig::from_toml("[agent]\ngamma = 0.9\n[env]\nvariant = \"end_to_end\"\n", "t.toml").unwrap();
        assert_eq!(cfg.agent.gamma, 0.9);
        assert_eq!(cfg.agent.batch_size, 32);
        assert_eq!(cfg.scalar_inputs(), 1);
    }

    #[test]
    fn bad_action_sets_stacks_and_reward_weights_are_refused_naming_the_field() {
        let e = RunConfig::from_toml("[agent]\naction_set = \"full\"\n", "run.toml").unwrap_err().to_string();
        assert!(e.contains("action_set") && e.contains("unknown variant `full`") && e.contains("`full27`"), "{e}");
        let e = RunConfig::from_toml("[env.camera]\nstack = 0\n", "run.toml").unwrap_err().to_string();
        assert_eq!(e, "config file run.toml: field `env.camera.stack`: 0 frames is outside 1..=8 (1: a single frame)");
        let e = RunConfig::from_toml("[env.reward]\nkind = \"progress\"\nlane_weight = nan\n", "run.toml").unwrap_err().to_string();
        assert!(e.contains("field `env.reward.lane_weight`"), "{e}");
    }

    #[test]
    fn a_checkpoint_with_another_action_set_or_stack_is_refused_naming_both() {
        let run = RunConfig::preset("hybrid-tuned").unwrap();
        run.check_checkpoint_body(&run.clone()).unwrap();
        let mut other = run.clone();
        other.agent.action_set = ActionSet::Full15;
        let e = run.check_checkpoint_body(&other).unwrap_err();
        assert!(
            e.starts_with(
                "agent.action_set: the checkpoint was trained with `full15` (15 actions), this run is configured with `paper6` (6 actions)"
            ),
            "{e}"
        );
        let mut other = run.clone();
        other.env.camera.as_mut().unwrap().stack = 4;
        let e = run.check_checkpoint_body(&other).unwrap_err();
        assert!(e.starts_with("env.camera.stack: the checkpoint sees 4 frame(s), this run is configured with 1"), "{e}");
    }

    #[test]
    fn errors_name_the_field() {
        let e = RunConfig::from_toml("[agent]\ngamma = 1.5\n", "run.toml").unwrap_err();
        assert_eq!(e.to_string(), "config file run.toml: field `agent.gamma`: 1.5 must be in (0, 1]");
        let e = RunConfig::from_toml("[env.reward]\nd0 = -2\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("field `env.reward.d0`"), "{e}");
        let e = RunConfig::from_toml("[agent]\npath_features = true\n[env]\nvariant = \"end_to_end\"\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("field `agent.path_features`: needs env.variant = \"hybrid\""), "{e}");
        let e = RunConfig::from_toml("[agent]\ntarget_tau = 1.5\n", "run.toml").unwrap_err();
        assert_eq!(
            e.to_string(),
            "config file run.toml: field `agent.target_tau`: 1.5 must be in [0, 1] (0: copy every target_update_period updates)"
        );
        let e = RunConfig::from_toml("[agent]\nbatch = 3\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("unknown field `batch`"), "{e}");
    }
}
