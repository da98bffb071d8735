//! A checkpoint's Q-network driving greedily (ε = 0: always the action of highest Q, ties to the
//! lowest index): loading it from any path a user gives (`agent::checkpoint::resolve`, checked
//! against its manifest) and the one batched inference call that `actor eval` and `actor drive
//! --policy CHECKPOINT` share.

use std::path::{Path, PathBuf};

use agent::checkpoint::{self, CONFIG, Progress, STATE};
use agent::config::RunConfig;
use agent::fastnet::Inference;
use anyhow::{Context, Result};
use serde::Serialize;
use sim_core::env::Env;
use sim_core::vehicle::Action;

/// The exploration rate of evaluation: none, the greedy policy.
pub const EPSILON: f32 = 0.0;

/// A checkpoint's Q-network and the configuration it was trained with.
#[derive(Debug)]
pub struct GreedyAgent {
    /// The configuration saved with the checkpoint.
    pub cfg: RunConfig,
    net: Inference,
    /// The action set, indexed by the network's outputs.
    pub actions: &'static [Action],
    /// Where it came from, for the report.
    pub source: CheckpointInfo,
}

/// Where a checkpoint was found and how far its training had got.
#[derive(Debug, Clone, Serialize)]
pub struct CheckpointInfo {
    /// The online weights file read.
    pub weights: PathBuf,
    /// The run directory, if the checkpoint sits in one.
    pub run_dir: Option<PathBuf>,
    pub learner_step: Option<u64>,
    pub env_steps: Option<u64>,
    pub episodes: Option<u64>,
}

impl GreedyAgent {
    /// A network of `cfg` with the parameters of `weights` (a safetensors file, as the learner
    /// publishes and checkpoints them), on `threads` threads.
    pub fn from_weights(cfg: RunConfig, weights: &[u8], threads: usize, source: CheckpointInfo) -> Result<Self> {
        let (mut net, _) = Inference::with_precision(cfg.net_shape(), cfg.agent.seed, threads, cfg.agent.precision);
        net.load(weights).context("the weights do not fit the run's network")?;
        let actions = cfg.agent.action_set.actions();
        Ok(Self { cfg, net, actions, source })
    }
}

/// Loads a checkpoint given as a run directory, a checkpoint directory or its weights file. The
/// files the checkpoint's manifest lists are checked against it.
pub fn load_checkpoint(path: &Path) -> Result<GreedyAgent> {
    let found = checkpoint::resolve(path)?;
    let config_path = found.dir.join(CONFIG);
    let files = checkpoint::read_verified_subset(&found.dir, &[&found.weights, &config_path])?;
    let [bytes, config_bytes] = <[Vec<u8>; 2]>::try_from(files).expect("two files asked for, two read");
    let text = String::from_utf8(config_bytes).with_context(|| format!("checkpoint file {} is not UTF-8 text", config_path.display()))?;
    let cfg = RunConfig::from_toml(&text, &config_path.display().to_string())?;
    let shape = cfg.net_shape();
    let (mut net, _) = Inference::with_precision(shape, cfg.agent.seed, agent::fastnet::default_threads(), cfg.agent.precision);
    net.load(&bytes).with_context(|| {
        format!(
            "checkpoint weights {} do not fit the network its {} describes ({}x{}x{} input, {} scalars, {} actions)",
            found.weights.display(),
            config_path.display(),
            shape.width,
            shape.height,
            shape.channels,
            shape.scalars,
            shape.actions
        )
    })?;
    let progress = std::fs::read(found.dir.join(STATE)).map(|b| Progress::from_state_json(&b)).unwrap_or_default();
    let source = CheckpointInfo {
        weights: found.weights,
        run_dir: found.run_dir,
        learner_step: progress.learner_step,
        env_steps: progress.env_steps,
        episodes: progress.episodes,
    };
    let actions = cfg.agent.action_set.actions();
    Ok(GreedyAgent { cfg, net, actions, source })
}

/// The greedy actions (indices into the action set) of `agent` for each environment: one batched
/// forward pass of the Q-network (the actors' fast path; the first of equal Q values).
pub fn greedy_actions(agent: &mut GreedyAgent, envs: &[&Env]) -> Vec<u32> {
    let scalars = agent::features::env_inputs(&agent.cfg, envs.iter().copied());
    agent.net.greedy(envs.iter().map(|e| e.stacked_image().data.as_slice()), &scalars)
}

/// The Q values (one per action) of one observation: an image (`H × W × C·stack` bytes, the
/// camera's stacked frames, `Env::stacked_image`) and the network's scalar inputs (`agent::features::scalar_features`).
pub fn q_values(agent: &mut GreedyAgent, image: &[u8], scalars: &[f32]) -> Vec<f32> {
    agent.net.q_values([image], scalars).to_vec()
}

/// The greedy action of `agent` in `env`.
pub fn greedy_action(agent: &mut GreedyAgent, env: &Env) -> Action {
    agent.actions[greedy_actions(agent, &[env])[0] as usize]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{tiny_config, write_checkpoint};
    use sim_core::config::Variant;

    #[test]
    fn what_is_not_a_checkpoint_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_checkpoint(dir.path()).unwrap_err().to_string();
        assert!(e.contains(&dir.path().display().to_string()) && e.contains("is not a checkpoint"), "{e}");
        let missing = dir.path().join("nope");
        let e = load_checkpoint(&missing).unwrap_err().to_string();
        assert!(e.contains("no such file") && e.contains("nope"), "{e}");
        let stray = dir.path().join("w.safetensors");
        std::fs::write(&stray, b"x").unwrap();
        let e = load_checkpoint(&stray).unwrap_err().to_string();
        assert!(e.contains("config.toml is missing"), "{e}");
        let text = dir.path().join("notes.txt");
        std::fs::write(&text, b"x").unwrap();
        assert!(load_checkpoint(&text).unwrap_err().to_string().contains("is not a checkpoint"));
    }

    #[test]
    fn corrupt_or_mismatched_weights_are_refused_with_the_file_named() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = tiny_config(Variant::Hybrid);
        let ckpt = write_checkpoint(dir.path(), &cfg);
        let weights = ckpt.join("online.safetensors");
        let mut bytes = std::fs::read(&weights).unwrap();
        let last = bytes.len() - 1;
        bytes[last] ^= 1;
        std::fs::write(&weights, &bytes).unwrap();
        let e = format!("{:#}", load_checkpoint(dir.path()).unwrap_err());
        assert!(e.contains("online.safetensors") && e.contains("checksum"), "{e}");
        // A config that describes another network than the weights (no manifest to catch it).
        std::fs::remove_file(ckpt.join("manifest.json")).unwrap();
        bytes[last] ^= 1;
        std::fs::write(&weights, &bytes).unwrap();
        let mut other = cfg.clone();
        other.agent.hidden = 9;
        std::fs::write(ckpt.join("config.toml"), other.to_toml()).unwrap();
        let e = format!("{:#}", load_checkpoint(&weights).unwrap_err());
        assert!(e.contains("do not fit the network") && e.contains("has shape"), "{e}");
    }
}
