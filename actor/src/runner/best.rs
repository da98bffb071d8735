//! `RUN_DIR/best/`: the weights that scored highest in the run's periodic greedy evaluations
//! (validation seeds no final evaluation uses), kept beside the latest checkpoint. The last
//! weights of a run are one draw of a policy that swings between evaluations; `best/` is the one
//! its validation chose. It is a checkpoint `actor eval --checkpoint RUN_DIR/best` reads like any
//! other: `online.safetensors`, `config.toml`, a `state.json` with the learner's counters, a
//! `manifest.json` over the three, and `best.json`, the evaluation that chose it.
//!
//! Replaced atomically: written into `best.tmp/`, then renamed over `best/` (the previous one
//! waits as `best.old/` for the instant between), so a crash leaves one whole `best/`.

use std::fs;
use std::path::{Path, PathBuf};

use agent::checkpoint::{CONFIG, MANIFEST, ONLINE, STATE, manifest_of};
use anyhow::{Context, Result};

/// The directory of the best weights in a run directory.
pub const DIR: &str = "best";
/// The evaluation that chose them.
pub const RECORD: &str = "best.json";
const TMP: &str = "best.tmp";
const OLD: &str = "best.old";

/// The best directory of `run_dir`.
#[must_use]
pub fn dir(run_dir: &Path) -> PathBuf {
    run_dir.join(DIR)
}

/// The selection score of the evaluation that chose the run's `best/`, if it has one (left by an
/// interrupted swap: `best.old/`). A record that does not read is reported and treated as none:
/// the next evaluation writes a new one. (The record is `eval.jsonl`'s line, which the learner
/// crate defines and `runner/mod.rs` writes; only its `selection_score` is read here.)
#[must_use]
pub fn current(run_dir: &Path) -> Option<f64> {
    [DIR, OLD].into_iter().map(|d| run_dir.join(d).join(RECORD)).find(|p| p.is_file()).and_then(|path| {
        let read = fs::read(&path).map_err(anyhow::Error::from).and_then(|b| {
            let v: serde_json::Value = serde_json::from_slice(&b)?;
            v["selection_score"].as_f64().ok_or_else(|| anyhow::anyhow!("no number `selection_score`"))
        });
        read.map_err(|e| tracing::warn!("{}: {e:#}; the next periodic evaluation chooses best/ afresh", path.display())).ok()
    })
}

/// Whether `score` beats the best so far: strictly higher (a tie keeps the earlier).
#[must_use]
pub fn beats(score: f64, best: Option<f64>) -> bool {
    best.is_none_or(|b| score > b)
}

/// The learner's counters at the weights kept: `state.json`'s, as a checkpoint has them.
#[derive(Debug, Clone, Copy)]
pub struct Counters {
    pub learner_step: u64,
    pub env_steps: u64,
}

/// Writes `weights` (safetensors), the run's configuration, the counters and `record` (the JSON of
/// the evaluation that chose them) as the run's `best/`.
pub fn save(run_dir: &Path, weights: &[u8], config_toml: &str, counters: Counters, record: &[u8]) -> Result<PathBuf> {
    let tmp = run_dir.join(TMP);
    if tmp.exists() {
        fs::remove_dir_all(&tmp).with_context(|| format!("removing {}", tmp.display()))?;
    }
    fs::create_dir_all(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
    let state = serde_json::to_vec_pretty(&serde_json::json!({
        "counters": { "learner_step": counters.learner_step, "env_steps": counters.env_steps },
    }))?;
    let manifest = serde_json::to_vec_pretty(&manifest_of([(ONLINE, weights), (CONFIG, config_toml.as_bytes()), (STATE, &state[..])]))?;
    for (name, bytes) in [(ONLINE, weights), (CONFIG, config_toml.as_bytes()), (STATE, &state), (RECORD, record), (MANIFEST, &manifest)] {
        let path = tmp.join(name);
        let file = fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        use std::io::Write;
        let mut w = std::io::BufWriter::new(file);
        w.write_all(bytes).and_then(|()| w.flush()).with_context(|| format!("writing {}", path.display()))?;
        w.get_ref().sync_all().with_context(|| format!("syncing {}", path.display()))?;
    }
    let (best, old) = (dir(run_dir), run_dir.join(OLD));
    if old.exists() {
        fs::remove_dir_all(&old).with_context(|| format!("removing {}", old.display()))?;
    }
    if best.exists() {
        fs::rename(&best, &old).with_context(|| format!("moving {} aside", best.display()))?;
    }
    fs::rename(&tmp, &best).with_context(|| format!("renaming {} to {}", tmp.display(), best.display()))?;
    if old.exists() {
        fs::remove_dir_all(&old).with_context(|| format!("removing {}", old.display()))?;
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{tiny_config, write_checkpoint};
    use sim_core::config::Variant;

    fn save_scored(run: &Path, weights: &[u8], cfg: &agent::config::RunConfig, score: f64, env_steps: u64) {
        let record = serde_json::to_vec(&serde_json::json!({"env_steps": env_steps, "selection_score": score})).unwrap();
        save(run, weights, &cfg.to_toml(), Counters { learner_step: env_steps / 4, env_steps }, &record).unwrap();
    }

    #[test]
    fn the_best_weights_are_a_checkpoint_actor_eval_reads_and_a_better_score_replaces_them() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path();
        let cfg = tiny_config(Variant::Hybrid);
        write_checkpoint(run, &cfg);
        assert!(current(run).is_none());
        assert!(beats(0.1, None));
        let weights = fs::read(run.join("checkpoint").join(ONLINE)).unwrap();
        save_scored(run, &weights, &cfg, 0.4, 1000);
        let agent = crate::eval::greedy::load_checkpoint(&dir(run)).unwrap();
        assert_eq!((agent.source.env_steps, agent.source.learner_step), (Some(1000), Some(250)));
        let kept = current(run);
        assert_eq!(kept, Some(0.4));
        // A tie or a lower score does not replace it; a higher one does, and leaves no temporary.
        assert!(!beats(0.4, kept));
        assert!(!beats(0.3, kept));
        assert!(beats(0.5, kept));
        save_scored(run, &weights, &cfg, 0.5, 2000);
        assert_eq!(current(run), Some(0.5));
        assert_eq!(crate::eval::greedy::load_checkpoint(&dir(run)).unwrap().source.env_steps, Some(2000));
        assert!(!run.join(TMP).exists() && !run.join(OLD).exists());
        // Its manifest is checked: damaged weights are refused, not driven.
        fs::write(dir(run).join(ONLINE), b"damaged").unwrap();
        let e = crate::eval::greedy::load_checkpoint(&dir(run)).unwrap_err();
        assert!(format!("{e:#}").contains(ONLINE), "{e:#}");
    }

    #[test]
    fn a_best_record_that_does_not_read_counts_as_none() {
        let tmp = tempfile::tempdir().unwrap();
        fs::create_dir_all(dir(tmp.path())).unwrap();
        fs::write(dir(tmp.path()).join(RECORD), b"{not json").unwrap();
        assert!(current(tmp.path()).is_none());
    }
}
