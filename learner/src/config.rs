//! The run's configuration: one TOML file with `[env]` (the simulator, see `sim_core::config`),
//! `[agent]` (network, replay and training) and `[service]` (the gRPC server and the run
//! directory). Every field has a documented default; values are validated at load with errors that
//! name the field.
//!
//! A file may start from a named preset ([`PRESETS`]): `preset = "paper"` (or `"end-to-end"`) at
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
use sim_core::camera::CameraConfig;
use sim_core::config::{EnvConfig, Variant};
use sim_core::reward::RewardConfig;

/// The named presets, with what each is.
pub const PRESETS: [(&str, &str); 4] = [
    ("paper", "the paper's hybrid agent: d in the observation, r_w in the reward; plain one-step DQN, uniform replay"),
    ("end-to-end", "the paper's baseline: the same network and training, camera and speed only (no d input, no r_w)"),
    (
        "hybrid-tuned",
        "`paper` tuned for a 2-core CPU: 48x48 camera, double DQN, 3-step returns, target copied every 250 updates, \
         faster exploration decay, and the planner's signed path features as inputs",
    ),
    ("end-to-end-tuned", "`end-to-end` with the same tuning (no planner input, so no path features)"),
];

/// The whole configuration of a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunConfig {
    /// The named preset the file starts from (`paper`, `end-to-end`); the file's other values
    /// override it. Default: none, the built-in defaults.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    pub env: EnvConfig,
    pub agent: AgentConfig,
    pub service: ServiceConfig,
}

/// The DQN agent and its training.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AgentConfig {
    /// Discrete actions (default `paper6`, the paper code's six).
    pub action_set: ActionSet,
    /// Filters of each of the three convolution layers (default 64, the paper's).
    pub conv_filters: usize,
    /// Units of each of the two hidden fully connected layers (default 256, the paper's).
    pub hidden: usize,
    /// Discount γ (default 0.99).
    pub gamma: f32,
    /// Adam learning rate (default 2.5e-4).
    pub learning_rate: f64,
    /// Transitions per update (default 32).
    pub batch_size: usize,
    /// Replay capacity, transitions (default 100 000).
    pub replay_capacity: usize,
    /// Replay memory cap, bytes, frames included (default 2 GiB).
    pub replay_max_bytes: u64,
    /// Transitions stored before training starts (default 1 000).
    pub min_replay: usize,
    /// Samples trained per transition inserted (default 0.25: one batch of 32 per 128 steps).
    pub replay_ratio: f32,
    /// Updates between target-network copies (default 1 000).
    pub target_update_period: u64,
    /// Gradients are rescaled to at most this global L2 norm (default 10).
    pub grad_clip_norm: f32,
    /// Huber loss threshold δ (default 1).
    pub huber_delta: f32,
    /// Extension switch: double DQN targets, the online network choosing the next action and the
    /// target network valuing it (van Hasselt 2016) (default false: the paper's plain DQN).
    pub double_dqn: bool,
    /// Extension switch: prioritized replay, sampling by TD error (Schaul 2016) (default false:
    /// uniform, the paper's).
    pub prioritized_replay: bool,
    /// Prioritization exponent α (default 0.6) and importance-sampling exponent β (default 0.4).
    pub priority_alpha: f32,
    pub priority_beta: f32,
    /// Extension switch: n-step returns, 1..=32 (default 1, the paper's one-step targets).
    pub n_step: usize,
    /// Extension switch, hybrid agent only: the network also sees the planner's path as signed
    /// numbers (lateral offset, heading angles to the route near and 25 m ahead; sim-core's
    /// `Env::path_features`), not only the paper's unsigned d (default false).
    pub path_features: bool,
    /// Exploration: ε decays linearly from `epsilon_start` to `epsilon_end` over
    /// `epsilon_decay_steps` environment steps (defaults 1.0, 0.05, 200 000).
    pub epsilon_start: f32,
    pub epsilon_end: f32,
    pub epsilon_decay_steps: u64,
    /// Extension switch: per-actor ε (Ape-X: ε_i = ε^(1 + α·i/(N−1)), i the actor's index, N = `apex_actors`)
    /// instead of the schedule (default false; ε = 0.4, α = 7, N = 8).
    pub per_actor_epsilon: bool,
    pub apex_epsilon: f32,
    pub apex_alpha: f32,
    pub apex_actors: u32,
    /// Updates between weight publications to actors (default 10).
    pub publish_every_updates: u64,
    /// Seed of network initialisation and replay sampling (default 0).
    pub seed: u64,
}

impl Default for AgentConfig {
    fn default() -> Self {
        Self {
            action_set: ActionSet::Paper6,
            conv_filters: 64,
            hidden: 256,
            gamma: 0.99,
            learning_rate: 2.5e-4,
            batch_size: 32,
            replay_capacity: 100_000,
            replay_max_bytes: 2 << 30,
            min_replay: 1_000,
            replay_ratio: 0.25,
            target_update_period: 1_000,
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
            publish_every_updates: 10,
            seed: 0,
        }
    }
}

/// The server and its run directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ServiceConfig {
    /// gRPC listen address (default 127.0.0.1:50051).
    pub listen: String,
    /// Run directory: effective config, checkpoints, metrics (default `runs/default`).
    pub run_dir: String,
    /// Seconds between checkpoints (default 300).
    pub checkpoint_interval_secs: u64,
    /// Largest gRPC message accepted or sent, bytes (default 64 MiB: a weights message is ~7 MB
    /// for the paper network, a batch of 256 84×84 RGB transitions ~5.4 MB).
    pub max_message_bytes: usize,
    /// Seconds of silence after which an actor counts as disconnected (default 30).
    pub actor_timeout_secs: u64,
    /// Episodes in the rolling statistics of the status (default 100).
    pub stats_window: usize,
}

impl Default for ServiceConfig {
    fn default() -> Self {
        Self {
            listen: "127.0.0.1:50051".into(),
            run_dir: "runs/default".into(),
            checkpoint_interval_secs: 300,
            max_message_bytes: 64 << 20,
            actor_timeout_secs: 30,
            stats_window: 100,
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
        let cfg = match &own.preset {
            None => own,
            Some(name) => {
                let base = Self::preset(name).map_err(|m| invalid(("preset".into(), m)))?;
                let mut merged = toml::Table::try_from(&base).expect("a configuration converts to a TOML table");
                merge_tables(&mut merged, toml::from_str::<toml::Table>(text).map_err(parse_error)?);
                merged.try_into().map_err(parse_error)?
            }
        };
        cfg.validate().map_err(invalid)?;
        Ok(cfg)
    }

    /// The preset named `name` (see [`PRESETS`]); the error lists the valid names.
    ///
    /// `paper` is the paper-faithful hybrid agent (Yurtsever et al. 2020; SPEC §1): the paper's
    /// reward (ε = 5 m, v0 = 50 km/h, d0 = 8 m, all β = 1, collision −1, arrival +100, no
    /// clipping), d as a network input, the paper's network (three conv layers of 64 3×3 filters
    /// with 2×2 average pooling, two fully connected layers of 256), the paper code's six actions,
    /// γ = 0.99, waypoints every 8 m, training routes of 50–150 m, and plain one-step DQN with
    /// uniform replay — every extension switch off. What the paper does not state (learning rate,
    /// batch, replay size, exploration schedule, camera resolution: 84×84 gray) keeps this
    /// program's defaults. `end-to-end` is the same with `env.variant = "end_to_end"`: the network
    /// sees camera and speed only and the reward has no r_w (SPEC §1, the paper's baseline).
    /// `hybrid-tuned` and `end-to-end-tuned` are those two with the same tuning for a short
    /// budget on a CPU, and the hybrid one sees the planner's path features (`agent.path_features`).
    pub fn preset(name: &str) -> Result<Self, String> {
        let mut cfg = Self::default();
        let (variant, tuned) = match name {
            "paper" => (Variant::Hybrid, false),
            "end-to-end" => (Variant::EndToEnd, false),
            "hybrid-tuned" => (Variant::Hybrid, true),
            "end-to-end-tuned" => (Variant::EndToEnd, true),
            other => {
                let names: Vec<&str> = PRESETS.iter().map(|p| p.0).collect();
                return Err(format!("unknown preset `{other}`: expected one of {}", names.join(", ")));
            }
        };
        cfg.preset = Some(name.to_owned());
        let env = &mut cfg.env;
        env.variant = variant;
        env.reward = RewardConfig {
            collision: -1.0,
            arrival: 100.0,
            arrival_radius: 5.0,
            v0_kmh: 50.0,
            d0: 8.0,
            beta_v: 1.0,
            beta_l: 1.0,
            beta_w: 1.0,
            clip: None,
        };
        env.dt = 0.1;
        env.waypoint_spacing = 8.0;
        env.route_length_min = 50.0;
        env.route_length_max = 150.0;
        env.camera = Some(CameraConfig::default());
        let a = &mut cfg.agent;
        a.action_set = ActionSet::Paper6;
        a.conv_filters = 64;
        a.hidden = 256;
        a.gamma = 0.99;
        a.double_dqn = false;
        a.prioritized_replay = false;
        a.n_step = 1;
        a.path_features = false;
        a.per_actor_epsilon = false;
        if tuned {
            // What a 90-minute budget on two cores asks for (docs/RESULTS.md): a smaller image
            // makes updates and actor inference about 3x cheaper; double DQN, 3-step returns and
            // frequent target copies spread the reward faster per update.
            let camera = cfg.env.camera.as_mut().expect("set above");
            (camera.width, camera.height) = (48, 48);
            a.double_dqn = true;
            a.n_step = 3;
            a.target_update_period = 250;
            a.epsilon_decay_steps = 100_000;
            a.path_features = variant == Variant::Hybrid;
        }
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
        if s.stats_window == 0 {
            return Err(("service.stats_window".into(), "must be at least 1".into()));
        }
        if self.env.camera.is_none() {
            return Err(("env.camera".into(), "the agent drives from the camera: a camera must be configured".into()));
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

    /// Scalar inputs of the network besides the image: speed; d for the hybrid agent; and its
    /// path features with `agent.path_features`.
    #[must_use]
    pub fn scalar_inputs(&self) -> usize {
        match self.env.variant {
            Variant::Hybrid if self.agent.path_features => 2 + sim_core::env::PATH_FEATURES,
            Variant::Hybrid => 2,
            Variant::EndToEnd => 1,
        }
    }
}

/// Overlays `top` on `base`: tables merge key by key, any other value replaces.
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
    fn partial_files_take_defaults() {
        let cfg = RunConfig::from_toml("[agent]\ngamma = 0.9\n[env]\nvariant = \"end_to_end\"\n", "t.toml").unwrap();
        assert_eq!(cfg.agent.gamma, 0.9);
        assert_eq!(cfg.agent.batch_size, 32);
        assert_eq!(cfg.scalar_inputs(), 1);
    }

    #[test]
    fn errors_name_the_field() {
        let e = RunConfig::from_toml("[agent]\ngamma = 1.5\n", "run.toml").unwrap_err();
        assert_eq!(e.to_string(), "config file run.toml: field `agent.gamma`: 1.5 must be in (0, 1]");
        let e = RunConfig::from_toml("[env.reward]\nd0 = -2\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("field `env.reward.d0`"), "{e}");
        let e = RunConfig::from_toml("[agent]\npath_features = true\n[env]\nvariant = \"end_to_end\"\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("field `agent.path_features`: needs env.variant = \"hybrid\""), "{e}");
        let e = RunConfig::from_toml("[agent]\nbatch = 3\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("unknown field `batch`"), "{e}");
    }

    #[test]
    fn presets_are_the_paper_with_every_extension_off() {
        for name in ["paper", "end-to-end"] {
            let cfg = RunConfig::preset(name).unwrap();
            cfg.validate().unwrap();
            assert_eq!(cfg.preset.as_deref(), Some(name));
            let a = &cfg.agent;
            assert!(!a.double_dqn && !a.prioritized_replay && !a.per_actor_epsilon && a.n_step == 1, "{name}: {a:?}");
            assert_eq!((a.conv_filters, a.hidden, a.action_set), (64, 256, ActionSet::Paper6));
            assert_eq!((cfg.env.reward.d0, cfg.env.reward.v0_kmh, cfg.env.reward.arrival), (8.0, 50.0, 100.0));
        }
        let paper = RunConfig::preset("paper").unwrap();
        let e2e = RunConfig::preset("end-to-end").unwrap();
        assert_eq!((paper.scalar_inputs(), e2e.scalar_inputs()), (2, 1));
        // The two differ in the variant (and the name) only.
        let same = RunConfig { preset: paper.preset.clone(), env: EnvConfig { variant: Variant::Hybrid, ..e2e.env.clone() }, ..e2e };
        assert_eq!(same, paper);
        let e = RunConfig::preset("papr").unwrap_err();
        assert_eq!(e, "unknown preset `papr`: expected one of paper, end-to-end, hybrid-tuned, end-to-end-tuned");
    }

    #[test]
    fn tuned_presets_share_the_tuning_and_differ_in_the_planner_inputs() {
        let hybrid = RunConfig::preset("hybrid-tuned").unwrap();
        let e2e = RunConfig::preset("end-to-end-tuned").unwrap();
        hybrid.validate().unwrap();
        e2e.validate().unwrap();
        assert_eq!((hybrid.scalar_inputs(), e2e.scalar_inputs()), (5, 1));
        assert!(hybrid.agent.double_dqn && hybrid.agent.n_step == 3 && hybrid.agent.path_features);
        // Reward and network are the paper's.
        let paper = RunConfig::preset("paper").unwrap();
        assert_eq!((&hybrid.env.reward, hybrid.agent.conv_filters, hybrid.agent.hidden), (&paper.env.reward, 64, 256));
        let same = RunConfig {
            preset: hybrid.preset.clone(),
            env: EnvConfig { variant: Variant::Hybrid, ..e2e.env.clone() },
            agent: AgentConfig { path_features: true, ..e2e.agent.clone() },
            ..e2e
        };
        assert_eq!(same, hybrid);
    }

    #[test]
    fn a_file_overrides_its_preset_field_by_field() {
        let text = "preset = \"end-to-end\"\n[agent]\nlearning_rate = 0.001\n[env.camera]\nwidth = 32\n";
        let cfg = RunConfig::from_toml(text, "t.toml").unwrap();
        assert_eq!(cfg.env.variant, Variant::EndToEnd);
        assert_eq!(cfg.agent.learning_rate, 0.001);
        let cam = cfg.env.camera.as_ref().unwrap();
        assert_eq!((cam.width, cam.height), (32, 84), "only the width is overridden");
        // The effective file keeps the preset line and loads back to the same configuration.
        let written = cfg.to_toml();
        assert!(written.starts_with("preset = \"end-to-end\""), "{written}");
        assert_eq!(RunConfig::from_toml(&written, "back").unwrap(), cfg);
        // No preset: the defaults, and no preset line written.
        assert!(!RunConfig::default().to_toml().contains("preset"));
    }

    #[test]
    fn an_unknown_preset_names_the_field_and_the_choices() {
        let e = RunConfig::from_toml("preset = \"fast\"\n", "run.toml").unwrap_err();
        assert_eq!(
            e.to_string(),
            "config file run.toml: field `preset`: unknown preset `fast`: expected one of paper, end-to-end, hybrid-tuned, end-to-end-tuned"
        );
        let e = RunConfig::from_toml("preset = 3\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("preset"), "{e}");
        // Values set beside a preset are still validated.
        let e = RunConfig::from_toml("preset = \"paper\"\n[agent]\ngamma = 2.0\n", "run.toml").unwrap_err();
        assert!(e.to_string().contains("field `agent.gamma`"), "{e}");
    }
}
