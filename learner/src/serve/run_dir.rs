//! The run directory of `learner serve`: its configuration (the file, the checkpoint's on
//! `--resume`, the flags), the lock that makes it this process's, and the files that name it.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use super::ServeOptions;
use crate::storage::checkpoint;
use crate::storage::run_lock::RunLock;
use agent::config::RunConfig;

/// The file in a run directory that holds the address its learner listens on (written by
/// `learner serve` and `actor train` once bound; with port 0 it is the only way to find it).
pub const ADDR_FILE: &str = "server.addr";

/// The file in a run directory that holds the address of its Prometheus endpoint.
pub const METRICS_ADDR_FILE: &str = "metrics.addr";

/// A run directory opened for serving: its effective configuration, locked.
#[derive(Debug)]
pub(super) struct OpenedRun {
    pub cfg: RunConfig,
    pub run_dir: PathBuf,
    /// This process owns the run directory while the lock is held.
    pub lock: RunLock,
}

/// Locks the run directory of `opts` and works out its configuration: the file's (or the
/// defaults), the checkpoint's on `--resume` (the `[service]` section from the file), then the
/// flags; validated. A fresh run refuses a directory that holds a checkpoint.
pub(super) fn open(opts: &ServeOptions) -> Result<OpenedRun> {
    let mut cfg = match &opts.config {
        Some(p) => RunConfig::load(p)?,
        None => RunConfig::default(),
    };
    if let Some(dir) = &opts.run_dir {
        cfg.service.run_dir = dir.display().to_string();
    }
    let run_dir = PathBuf::from(&cfg.service.run_dir);
    std::fs::create_dir_all(&run_dir).with_context(|| format!("creating run directory {}", run_dir.display()))?;
    // Before anything is read: a second process on this run would corrupt it.
    let lock = RunLock::acquire(&run_dir)?;
    if opts.resume {
        let text = checkpoint_config_text(&run_dir)?;
        let from_ckpt = RunConfig::from_toml(&text, &format!("{}/checkpoint/config.toml", run_dir.display()))?;
        // What the network's inputs and outputs mean is named first, both values said.
        if opts.config.is_some() {
            cfg.check_checkpoint_body(&from_ckpt).map_err(|e| anyhow::anyhow!("--resume {}: {e}", run_dir.display()))?;
        }
        if opts.config.is_some() && from_ckpt.env != cfg.env {
            bail!(
                "--config describes another environment than the checkpoint in {}: resume without --config, or start a new run directory",
                run_dir.display()
            );
        }
        let service = cfg.service.clone();
        cfg = from_ckpt;
        cfg.service = service;
    } else if checkpoint::exists(&run_dir) {
        bail!("run directory {} already holds a checkpoint: pass --resume to continue it, or choose another --run-dir", run_dir.display());
    }
    if let Some(l) = &opts.listen {
        cfg.service.listen = l.clone();
    }
    for (flag, field) in [
        (&opts.tls_cert, &mut cfg.service.tls_cert),
        (&opts.tls_key, &mut cfg.service.tls_key),
        (&opts.tls_client_ca, &mut cfg.service.tls_client_ca),
    ] {
        if let Some(path) = flag {
            *field = path.display().to_string();
        }
    }
    cfg.validate().map_err(|(field, message)| anyhow::anyhow!("config field `{field}`: {message}"))?;
    Ok(OpenedRun { cfg, run_dir, lock })
}

/// The configuration saved with the checkpoint of `run_dir` (verified again, with everything else,
/// when the checkpoint is loaded).
pub(super) fn checkpoint_config_text(run_dir: &Path) -> Result<String> {
    for dir in [agent::checkpoint::DIR, agent::checkpoint::OLD_DIR] {
        let p = run_dir.join(dir).join(agent::checkpoint::CONFIG);
        if p.exists() {
            return std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()));
        }
    }
    bail!("--resume: run directory {} holds no checkpoint (expected {}/checkpoint/)", run_dir.display(), run_dir.display())
}

/// A run id: time-based, unique enough to tell runs apart.
pub(super) fn new_run_id() -> String {
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    format!("run-{}-{:04x}", t.as_secs(), (t.subsec_nanos() >> 8) & 0xffff)
}
