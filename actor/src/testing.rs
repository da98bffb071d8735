//! Test support: a tiny run configuration and a checkpoint written from the format alone.

use std::path::{Path, PathBuf};

use agent::checkpoint::{CONFIG, DIR, MANIFEST, ONLINE, STATE, manifest_of};
use agent::config::RunConfig;
use agent::fastnet::Params;
use sim_core::config::Variant;

/// `RunConfig::tiny` (a 16×16 camera, a tiny network) with the paper's environment of `variant`.
pub fn tiny_config(variant: Variant) -> RunConfig {
    let mut cfg = RunConfig::tiny(Path::new("unused"));
    let paper = RunConfig::preset(if variant == Variant::Hybrid { "paper" } else { "end-to-end" }).unwrap();
    cfg.env = sim_core::config::EnvConfig { camera: cfg.env.camera.clone(), ..paper.env };
    cfg
}

/// A freshly initialised checkpoint as the learner lays it out (`agent::checkpoint`): online
/// weights, config, state and a manifest of lengths and FNV-1a hashes. Written from the format
/// alone rather than through the learner, so that tests of the actor depend only on it.
pub fn write_checkpoint(run_dir: &Path, cfg: &RunConfig) -> PathBuf {
    let dir = run_dir.join(DIR);
    std::fs::create_dir_all(&dir).unwrap();
    let weights = agent::weights::to_safetensors(&Params::init(cfg.net_shape(), 1), "").unwrap();
    let state = serde_json::json!({"version": 1, "counters": {"learner_step": 7, "env_steps": 1234, "episodes": 9}});
    let files = [(ONLINE, weights), (CONFIG, cfg.to_toml().into_bytes()), (STATE, serde_json::to_vec(&state).unwrap())];
    for (name, bytes) in &files {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    let manifest = manifest_of(files.iter().map(|(n, b)| (*n, b.as_slice())));
    std::fs::write(dir.join(MANIFEST), serde_json::to_vec(&manifest).unwrap()).unwrap();
    dir
}
