//! Saving and loading the learner's whole state as a checkpoint (the format: `agent::checkpoint`).
//!
//! Saving writes everything into a fresh sibling directory `checkpoint.tmp-<pid>-<n>`, fsyncs the
//! files and the directory, then swaps it in ([`atomic`]): `checkpoint` → `checkpoint.old`, the
//! temporary directory → `checkpoint`, remove `checkpoint.old` (fsyncing the run directory after
//! the renames). Renames are atomic and `checkpoint` only ever names a complete directory, so
//! after a crash at any point there is a complete `checkpoint`, or (crash between the two renames)
//! only a complete `checkpoint.old`; [`load`] takes the first, else the second. One process writes
//! a run directory at a time.
//!
//! Loading verifies the manifest (every file present, lengths and hashes, version) and decodes and
//! shape-checks every file before it touches the [`Dqn`]: a refused checkpoint leaves the agent as
//! it was, and the error names the file and what is wrong with it.

mod atomic;

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use agent::checkpoint::{
    CONFIG, CheckpointError, Counters, FILES, FORMAT_VERSION, MANIFEST, OLD_DIR, ONLINE, OPTIMIZER, PREV_DIR, Progress, STATE, State,
    TARGET, TMP_PREFIX, locate, manifest_of, read_verified,
};
use agent::weights::{self, WeightsError};

use crate::training::dqn::Dqn;
use atomic::{io_error, remove_stale_temporaries, swap_in, sync_dir, write_synced};

pub use agent::checkpoint::{dir, exists};

/// What [`load`] returns besides the restored [`Dqn`].
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    pub counters: Counters,
    /// The run configuration saved with the checkpoint (TOML text).
    pub config_toml: String,
    /// Set when the newest checkpoint was unusable and the previous one was loaded: why, and
    /// what was lost.
    pub fell_back: Option<String>,
}

/// Saves the whole learner state into `run_dir/checkpoint/`, replacing any previous checkpoint
/// atomically (see the module documentation). Returns the checkpoint directory.
pub fn save(run_dir: &Path, dqn: &Dqn, counters: &Counters, config_toml: &str) -> Result<PathBuf, CheckpointError> {
    fs::create_dir_all(run_dir).map_err(io_error(run_dir, "creating the run directory"))?;
    let final_dir = dir(run_dir);
    let serialise = |name: &str, reason: String| CheckpointError::Serialise { path: final_dir.join(name), reason };

    let online = weights::to_safetensors(&dqn.online, "").map_err(|e| serialise(ONLINE, e.to_string()))?;
    let target = weights::to_safetensors(&dqn.target, "").map_err(|e| serialise(TARGET, e.to_string()))?;
    let optimizer = optimizer_safetensors(dqn).map_err(|e| serialise(OPTIMIZER, e.to_string()))?;
    let state = State {
        version: FORMAT_VERSION,
        counters: counters.clone(),
        adam_t: dqn.adam.t,
        learning_rate: dqn.adam.lr,
        elapsed_secs_bits: counters.elapsed_secs.to_bits(),
    };
    let state = serde_json::to_vec_pretty(&state).map_err(|e| serialise(STATE, e.to_string()))?;
    let contents: [&[u8]; 5] = [&online, &target, &optimizer, &state, config_toml.as_bytes()];
    let mut manifest = manifest_of(FILES.into_iter().zip(contents));
    manifest.vector_layout = agent::config::RunConfig::from_toml(config_toml, CONFIG).ok().and_then(|c| c.vector_layout());
    let manifest = serde_json::to_vec_pretty(&manifest).map_err(|e| serialise(MANIFEST, e.to_string()))?;

    static SAVES: AtomicU64 = AtomicU64::new(0);
    let pid = std::process::id();
    let tmp = run_dir.join(format!("{TMP_PREFIX}{pid}-{}", SAVES.fetch_add(1, Ordering::Relaxed)));
    if tmp.exists() {
        // Left by a crashed process that had our pid.
        fs::remove_dir_all(&tmp).map_err(io_error(&tmp, "removing a stale temporary directory"))?;
    }
    fs::create_dir(&tmp).map_err(io_error(&tmp, "creating the temporary directory"))?;
    let written = (|| {
        for (name, bytes) in FILES.iter().zip(contents).chain([(&MANIFEST, manifest.as_slice())]) {
            write_synced(&tmp.join(name), bytes)?;
        }
        sync_dir(&tmp)?;
        swap_in(run_dir, &tmp)
    })();
    if let Err(e) = written {
        // Nothing of ours is left behind; the previous checkpoint is intact (as `checkpoint`, or
        // as `checkpoint.old` if the first rename happened).
        let _ = fs::remove_dir_all(&tmp);
        return Err(e);
    }

    // The new checkpoint is committed: what follows is tidying, and its failures are only logged.
    // The one it replaced becomes the previous checkpoint (the one before goes).
    let old = run_dir.join(OLD_DIR);
    if old.exists() {
        let prev = run_dir.join(PREV_DIR);
        let kept = (|| {
            if prev.exists() {
                fs::remove_dir_all(&prev)?;
            }
            fs::rename(&old, &prev)
        })();
        if let Err(e) = kept {
            tracing::warn!("checkpoint saved, but keeping {} as {} failed: {e}", old.display(), prev.display());
            let _ = fs::remove_dir_all(&old);
        }
    }
    remove_stale_temporaries(run_dir, pid);
    if let Err(e) = sync_dir(run_dir) {
        tracing::warn!("{e}");
    }
    Ok(final_dir)
}

/// Loads the checkpoint of `run_dir` into `dqn` (online and target weights, Adam's moments and
/// step count, `dqn.updates` = `counters.learner_step`), and returns the counters and the saved
/// configuration. Uses `checkpoint/`, or `checkpoint.old/` if only that exists. Everything is
/// verified before `dqn` is touched: on error it is unchanged. Adam's learning rate stays the
/// `dqn`'s own.
pub fn load(run_dir: &Path, dqn: &mut Dqn) -> Result<Loaded, CheckpointError> {
    let newest = locate(run_dir)?;
    let err = match load_from(&newest, dqn) {
        Ok(loaded) => return Ok(loaded),
        Err(e @ (CheckpointError::Corrupt { .. } | CheckpointError::Missing { .. })) => e,
        Err(e) => return Err(e),
    };
    let prev = run_dir.join(PREV_DIR);
    if !prev.is_dir() {
        return Err(err);
    }
    let mut loaded = match load_from(&prev, dqn) {
        Ok(loaded) => loaded,
        // Both unusable: the newest's defect is the one to report.
        Err(_) => return Err(err),
    };
    let newest_step = fs::read(newest.join(STATE)).ok().and_then(|b| Progress::from_state_json(&b).learner_step);
    let lost = match newest_step {
        Some(n) => format!("the {} updates between them are lost", n.saturating_sub(loaded.counters.learner_step)),
        None => "the updates between them are lost".to_owned(),
    };
    let note = format!(
        "the newest checkpoint is unusable ({err}); resumed from the previous one, {} (learner step {}): {lost}; \
         the replay log still holds every acknowledged batch",
        prev.display(),
        loaded.counters.learner_step
    );
    tracing::warn!("{note}");
    loaded.fell_back = Some(note);
    Ok(loaded)
}

/// Loads the checkpoint directory `dir` (see [`load`]).
fn load_from(dir: &Path, dqn: &mut Dqn) -> Result<Loaded, CheckpointError> {
    let dir = dir.to_owned();
    let [online, target, optimizer, state, config] = read_verified(&dir)?;

    let state_path = dir.join(STATE);
    let state: State = serde_json::from_slice(&state)
        .map_err(|e| CheckpointError::Corrupt { path: state_path.clone(), reason: format!("unparsable JSON: {e}") })?;
    if state.version != FORMAT_VERSION {
        return Err(CheckpointError::UnsupportedVersion { path: state_path, found: state.version });
    }
    let mut counters = state.counters;
    let exact = f64::from_bits(state.elapsed_secs_bits);
    let close =
        exact == counters.elapsed_secs || (exact - counters.elapsed_secs).abs() <= 1e-12 * exact.abs().max(counters.elapsed_secs.abs());
    if !close {
        return Err(CheckpointError::Corrupt {
            path: state_path,
            reason: format!("elapsed_secs {} disagrees with elapsed_secs_bits ({exact})", counters.elapsed_secs),
        });
    }
    counters.elapsed_secs = exact;
    let config_toml = String::from_utf8(config)
        .map_err(|e| CheckpointError::Corrupt { path: dir.join(CONFIG), reason: format!("not UTF-8 text: {e}") })?;

    let decode = |bytes: &[u8], name: &str, prefix: &str| {
        let path = dir.join(name);
        weights::from_safetensors(dqn.shape, bytes, prefix).map_err(|e| match e {
            WeightsError::Mismatch(reason) => CheckpointError::Incompatible { path, reason },
            other => CheckpointError::Corrupt { path, reason: other.to_string() },
        })
    };
    let online = decode(&online, ONLINE, "")?;
    let target = decode(&target, TARGET, "")?;
    let m = decode(&optimizer, OPTIMIZER, "m.")?;
    let v = decode(&optimizer, OPTIMIZER, "v.")?;

    // Everything checked: commit.
    dqn.online = online;
    dqn.target = target;
    dqn.adam.m = m;
    dqn.adam.v = v;
    dqn.adam.t = state.adam_t;
    dqn.updates = counters.learner_step;
    Ok(Loaded { counters, config_toml, fell_back: None })
}

/// Adam's moments as a safetensors file: `m.<param>` and `v.<param>` for every slot.
fn optimizer_safetensors(dqn: &Dqn) -> Result<Vec<u8>, WeightsError> {
    weights::to_safetensors_multi(&[("m.", &dqn.adam.m), ("v.", &dqn.adam.v)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::training::dqn::{Batch, UpdateStats};
    use agent::NetShape;
    use agent::checkpoint::{DIR, Manifest};
    use agent::config::AgentConfig;
    use sim_core::hash::fnv1a64;

    fn shape() -> NetShape {
        NetShape { height: 8, width: 8, channels: 1, scalars: 2, actions: 2, filters: 2, hidden: 4 }
    }

    fn cfg() -> AgentConfig {
        // Target copied every 3 updates: after 4 updates online and target differ.
        AgentConfig { learning_rate: 1e-2, target_update_period: 3, seed: 7, ..AgentConfig::default() }
    }

    fn batch() -> Batch {
        let n = 4;
        let images: Vec<u8> = (0..n).flat_map(|i| (0..64).map(move |p| ((p * 7 + i * 50) % 256) as u8)).collect();
        // The next observations are the batch in reverse order.
        let next_images: Vec<u8> = images.chunks_exact(64).rev().flatten().copied().collect();
        Batch {
            images,
            scalars: vec![0.0; 2 * n],
            actions: vec![0, 1, 1, 0],
            rewards: vec![1.0, -0.5, 0.25, 0.0],
            next_images,
            next_scalars: vec![0.0; 2 * n],
            discounts: vec![0.9, 0.0, 0.9, 0.9],
            weights: vec![1.0; n],
            demos: 0,
        }
    }

    /// An agent after 4 updates (target synced at update 3, so target ≠ online, and Adam's
    /// moments are non-zero).
    fn trained(shape: NetShape) -> Dqn {
        let mut dqn = Dqn::new(shape, &cfg());
        let b = batch();
        for _ in 0..4 {
            dqn.update(&b);
        }
        dqn
    }

    fn counters() -> Counters {
        Counters {
            run_id: "run-42".into(),
            learner_step: 4,
            env_steps: 1234,
            transitions_received: 1200,
            transitions_stored: 1190,
            transitions_rejected: 10,
            batches_rejected: 2,
            episodes: 17,
            weights_version: 3,
            // serde_json 1.0's default parser reads this value's shortest decimal back one ulp off
            // (about one random value in ten is): `elapsed_secs_bits` keeps it exact.
            elapsed_secs: 3969.3421758078052,
            replay_log_position: 17,
            demo_transitions_received: 300,
            demo_transitions_stored: 299,
        }
    }

    const CONFIG_TOML: &str = "[agent]\ngamma = 0.9\n";

    /// Everything of a Dqn that a checkpoint covers.
    fn snapshot(dqn: &Dqn) -> (Vec<u8>, Vec<u8>, Vec<u8>, u64, u64) {
        (
            weights::to_safetensors(&dqn.online, "").unwrap(),
            weights::to_safetensors(&dqn.target, "").unwrap(),
            optimizer_safetensors(dqn).unwrap(),
            dqn.adam.t,
            dqn.updates,
        )
    }

    /// A fresh agent of `shape` initialised from another seed than the saved one.
    fn fresh(shape: NetShape) -> Dqn {
        Dqn::new(shape, &AgentConfig { seed: 8, ..cfg() })
    }

    /// Replaces a file of a checkpoint and updates the manifest to match, so that the defect
    /// reaches the decoding stage.
    fn rewrite(dir: &Path, name: &str, bytes: &[u8]) {
        fs::write(dir.join(name), bytes).unwrap();
        let mut m: Manifest = serde_json::from_slice(&fs::read(dir.join(MANIFEST)).unwrap()).unwrap();
        let e = m.files.iter_mut().find(|e| e.name == name).unwrap();
        e.bytes = bytes.len() as u64;
        e.fnv1a64 = format!("{:016x}", fnv1a64(bytes));
        fs::write(dir.join(MANIFEST), serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    }

    fn bits(s: &UpdateStats) -> (u32, u32, u32, Vec<u32>) {
        (s.loss.to_bits(), s.mean_q.to_bits(), s.grad_norm.to_bits(), s.td_abs.iter().map(|x| x.to_bits()).collect())
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn round_trip_is_bit_exact_and_resume_continues_exactly() {
        let tmp = tempfile::tempdir().unwrap();
        let mut saved = trained(shape());
        assert!(!exists(tmp.path()));
        let dir = save(tmp.path(), &saved, &counters(), CONFIG_TOML).unwrap();
        assert_eq!(dir, tmp.path().join("checkpoint"));
        assert!(exists(tmp.path()));
        assert_eq!(
            entries(&dir),
            ["config.toml", "manifest.json", "online.safetensors", "optimizer.safetensors", "state.json", "target.safetensors"]
        );
        // The files hold exactly what the serialisers produce.
        assert_eq!(fs::read(dir.join(ONLINE)).unwrap(), weights::to_safetensors(&saved.online, "").unwrap());
        assert_eq!(fs::read(dir.join(TARGET)).unwrap(), weights::to_safetensors(&saved.target, "").unwrap());
        assert_eq!(fs::read(dir.join(OPTIMIZER)).unwrap(), optimizer_safetensors(&saved).unwrap());
        assert_eq!(fs::read_to_string(dir.join(CONFIG)).unwrap(), CONFIG_TOML);

        let mut resumed = fresh(shape());
        assert_ne!(snapshot(&resumed), snapshot(&saved), "the fresh agent starts elsewhere");
        let loaded = load(tmp.path(), &mut resumed).unwrap();
        assert_eq!(loaded, Loaded { counters: counters(), config_toml: CONFIG_TOML.into(), fell_back: None });
        assert_eq!(loaded.counters.elapsed_secs.to_bits(), 3969.3421758078052f64.to_bits());
        let s = snapshot(&saved);
        assert_ne!(s.0, s.1, "online and target differ after 4 updates with a sync at 3");
        assert_eq!(snapshot(&resumed), s);
        assert_eq!((resumed.adam.t, resumed.updates), (4, 4));

        // Resuming continues exactly: same losses, statistics and weights, through a target sync
        // (updates 5 and 6; the period is 3).
        let b = batch();
        for _ in 0..2 {
            let a = saved.update(&b);
            let r = resumed.update(&b);
            assert_eq!(bits(&a), bits(&r));
            assert_eq!(snapshot(&resumed), snapshot(&saved));
        }
        assert_eq!(
            weights::to_safetensors(&saved.online, "").unwrap(),
            weights::to_safetensors(&saved.target, "").unwrap(),
            "synced at update 6"
        );
    }

    #[test]
    fn a_flipped_byte_is_refused_naming_the_file_and_the_agent_is_unchanged() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = save(tmp.path(), &trained(shape()), &counters(), CONFIG_TOML).unwrap();
        let path = dir.join(ONLINE);
        let mut bytes = fs::read(&path).unwrap();
        // The last byte is parameter data: the file still parses, only the checksum can tell.
        *bytes.last_mut().unwrap() ^= 0x01;
        fs::write(&path, &bytes).unwrap();
        let mut dqn = fresh(shape());
        let before = snapshot(&dqn);
        let e = load(tmp.path(), &mut dqn).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, CheckpointError::Corrupt { .. }), "{msg}");
        assert!(msg.starts_with(&format!("checkpoint {} is corrupt: checksum mismatch (expected ", path.display())), "{msg}");
        assert_eq!(snapshot(&dqn), before);
    }

    #[test]
    fn a_truncated_state_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = save(tmp.path(), &trained(shape()), &counters(), CONFIG_TOML).unwrap();
        let path = dir.join(STATE);
        let full = fs::read(&path).unwrap();
        let half = &full[..full.len() / 2];
        fs::write(&path, half).unwrap();
        let mut dqn = fresh(shape());
        let before = snapshot(&dqn);
        let msg = load(tmp.path(), &mut dqn).unwrap_err().to_string();
        assert_eq!(
            msg,
            format!("checkpoint {} is corrupt: truncated: {} bytes, the manifest records {}", path.display(), half.len(), full.len())
        );
        // With a manifest that agrees (truncated before the manifest was written), the JSON
        // parser refuses it.
        rewrite(&dir, STATE, half);
        let msg = load(tmp.path(), &mut dqn).unwrap_err().to_string();
        assert!(msg.starts_with(&format!("checkpoint {} is corrupt: unparsable JSON: EOF", path.display())), "{msg}");
        assert_eq!(snapshot(&dqn), before);
    }

    #[test]
    fn a_network_of_another_shape_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        save(tmp.path(), &trained(shape()), &counters(), CONFIG_TOML).unwrap();
        let mut wider = fresh(NetShape { hidden: 5, ..shape() });
        let before = snapshot(&wider);
        let e = load(tmp.path(), &mut wider).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, CheckpointError::Incompatible { .. }), "{msg}");
        // Parameters are checked in name order: the conv* ones fit, fc1.bias is [4] where 5 is
        // expected.
        let path = tmp.path().join("checkpoint").join(ONLINE);
        assert_eq!(
            msg,
            format!("checkpoint {} does not fit this network: parameter `fc1.bias` has shape [4], expected [5]", path.display())
        );
        assert_eq!(snapshot(&wider), before);
    }

    #[test]
    fn other_defects_are_refused_naming_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = save(tmp.path(), &trained(shape()), &counters(), CONFIG_TOML).unwrap();
        let mut dqn = fresh(shape());
        let before = snapshot(&dqn);
        let load_err = |dqn: &mut Dqn| load(tmp.path(), dqn).unwrap_err().to_string();

        // Optimizer moments of the wrong shape (a consistent manifest: only the decoder can tell).
        let good = fs::read(dir.join(OPTIMIZER)).unwrap();
        let other = optimizer_safetensors(&trained(NetShape { hidden: 5, ..shape() })).unwrap();
        rewrite(&dir, OPTIMIZER, &other);
        let msg = load_err(&mut dqn);
        assert!(msg.contains("optimizer.safetensors does not fit this network: tensor `m.fc1.bias` has shape [5], expected [4]"), "{msg}");
        rewrite(&dir, OPTIMIZER, &good);

        // A missing file.
        let config = fs::read(dir.join(CONFIG)).unwrap();
        fs::remove_file(dir.join(CONFIG)).unwrap();
        assert_eq!(load_err(&mut dqn), format!("checkpoint {} is missing", dir.join(CONFIG).display()));
        fs::write(dir.join(CONFIG), &config).unwrap();

        // Another format version.
        let manifest = fs::read_to_string(dir.join(MANIFEST)).unwrap();
        let mut future: Manifest = serde_json::from_str(&manifest).unwrap();
        future.version = 2;
        fs::write(dir.join(MANIFEST), serde_json::to_vec_pretty(&future).unwrap()).unwrap();
        assert_eq!(
            load_err(&mut dqn),
            format!("checkpoint {} has format version 2; this build reads version 1", dir.join(MANIFEST).display())
        );

        // An unparsable manifest.
        fs::write(dir.join(MANIFEST), &manifest[..10]).unwrap();
        let msg = load_err(&mut dqn);
        assert!(msg.starts_with(&format!("checkpoint {} is corrupt: unparsable JSON", dir.join(MANIFEST).display())), "{msg}");

        assert_eq!(snapshot(&dqn), before);
        // Repaired, it loads.
        fs::write(dir.join(MANIFEST), &manifest).unwrap();
        load(tmp.path(), &mut dqn).unwrap();

        // No checkpoint at all.
        let empty = tempfile::tempdir().unwrap();
        let msg = load(empty.path(), &mut dqn).unwrap_err().to_string();
        assert!(msg.starts_with(&format!("no checkpoint in {}", empty.path().display())), "{msg}");
    }

    #[test]
    fn a_crash_mid_swap_leaves_the_previous_checkpoint_loadable() {
        let tmp = tempfile::tempdir().unwrap();
        let saved = trained(shape());
        save(tmp.path(), &saved, &counters(), CONFIG_TOML).unwrap();
        // A crash between the two renames: `checkpoint` moved aside, the new one not yet in place
        // (its temporary directory is incomplete).
        fs::rename(tmp.path().join(DIR), tmp.path().join(OLD_DIR)).unwrap();
        fs::create_dir(tmp.path().join("checkpoint.tmp-4000000000-0")).unwrap();
        fs::write(tmp.path().join("checkpoint.tmp-4000000000-0").join(ONLINE), b"partial").unwrap();
        assert!(exists(tmp.path()));
        let mut dqn = fresh(shape());
        assert_eq!(load(tmp.path(), &mut dqn).unwrap().counters, counters());
        assert_eq!(snapshot(&dqn), snapshot(&saved));
        // The next save installs a checkpoint and tidies up: the stale directories are gone.
        let next = Counters { learner_step: 5, ..counters() };
        save(tmp.path(), &dqn, &next, CONFIG_TOML).unwrap();
        assert_eq!(entries(tmp.path()), ["checkpoint", "checkpoint.prev"]);
        assert_eq!(load(tmp.path(), &mut fresh(shape())).unwrap().counters, next);
    }

    #[test]
    fn saving_twice_leaves_the_latest_and_the_previous_checkpoint() {
        let tmp = tempfile::tempdir().unwrap();
        let mut dqn = trained(shape());
        save(tmp.path(), &dqn, &counters(), CONFIG_TOML).unwrap();
        dqn.update(&batch());
        let second = Counters { learner_step: 5, env_steps: 2000, ..counters() };
        save(tmp.path(), &dqn, &second, "[agent]\ngamma = 0.8\n").unwrap();
        assert_eq!(entries(tmp.path()), ["checkpoint", "checkpoint.prev"]);
        let mut resumed = fresh(shape());
        let loaded = load(tmp.path(), &mut resumed).unwrap();
        assert_eq!(loaded, Loaded { counters: second.clone(), config_toml: "[agent]\ngamma = 0.8\n".into(), fell_back: None });
        assert_eq!(snapshot(&resumed), snapshot(&dqn));
        // A third save keeps two, the second as the previous one.
        let third = Counters { learner_step: 6, ..second.clone() };
        save(tmp.path(), &dqn, &third, CONFIG_TOML).unwrap();
        assert_eq!(entries(tmp.path()), ["checkpoint", "checkpoint.prev"]);
        let state = fs::read(tmp.path().join(PREV_DIR).join(STATE)).unwrap();
        assert_eq!(Progress::from_state_json(&state).learner_step, Some(5));
    }

    /// The newest checkpoint's weights truncated on disk (issue: "one truncated file today ends
    /// the run"): the previous checkpoint is loaded instead, saying what was lost.
    #[test]
    fn a_damaged_newest_checkpoint_falls_back_to_the_previous_one() {
        let tmp = tempfile::tempdir().unwrap();
        let first = trained(shape());
        save(tmp.path(), &first, &counters(), CONFIG_TOML).unwrap();
        let mut newer = trained(shape());
        for _ in 0..3 {
            newer.update(&batch());
        }
        save(tmp.path(), &newer, &Counters { learner_step: 7, ..counters() }, CONFIG_TOML).unwrap();
        let online = tmp.path().join(DIR).join(ONLINE);
        let bytes = fs::read(&online).unwrap();
        fs::write(&online, &bytes[..1000]).unwrap();
        let mut dqn = fresh(shape());
        let loaded = load(tmp.path(), &mut dqn).unwrap();
        assert_eq!(loaded.counters, counters());
        assert_eq!(snapshot(&dqn), snapshot(&first));
        let note = loaded.fell_back.expect("says it fell back");
        assert!(note.contains(&format!("{} is corrupt: truncated", online.display())), "{note}");
        assert!(note.contains("(learner step 4): the 3 updates between them are lost"), "{note}");
        // Both damaged: the newest's defect is reported.
        let prev_online = tmp.path().join(PREV_DIR).join(ONLINE);
        fs::write(&prev_online, b"x").unwrap();
        let e = load(tmp.path(), &mut fresh(shape())).unwrap_err().to_string();
        assert!(e.starts_with(&format!("checkpoint {} is corrupt", online.display())), "{e}");
    }
}
