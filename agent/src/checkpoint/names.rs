//! The names of a checkpoint's directory and files, and the format version.

use std::path::{Path, PathBuf};

/// The format written, and the only one read.
pub const FORMAT_VERSION: u32 = 1;
/// The checkpoint directory inside the run directory.
pub const DIR: &str = "checkpoint";
/// Where the previous checkpoint waits while a new one is swapped in.
pub const OLD_DIR: &str = "checkpoint.old";
/// The checkpoint before the newest, kept so that a newest one damaged on disk is not the end of
/// the run: a resume falls back to it.
pub const PREV_DIR: &str = "checkpoint.prev";
/// Prefix of the temporary directories a save writes into.
pub const TMP_PREFIX: &str = "checkpoint.tmp-";

pub const ONLINE: &str = "online.safetensors";
pub const TARGET: &str = "target.safetensors";
pub const OPTIMIZER: &str = "optimizer.safetensors";
pub const STATE: &str = "state.json";
pub const CONFIG: &str = "config.toml";
pub const MANIFEST: &str = "manifest.json";

/// The files the manifest covers, in the order they are written and verified.
pub const FILES: [&str; 5] = [ONLINE, TARGET, OPTIMIZER, STATE, CONFIG];

/// The checkpoint directory of `run_dir`.
#[must_use]
pub fn dir(run_dir: &Path) -> PathBuf {
    run_dir.join(DIR)
}

/// Whether `run_dir` holds a checkpoint (complete, or left as `checkpoint.old` by a crash during a
/// swap). Says nothing of its integrity: reading checks that.
#[must_use]
pub fn exists(run_dir: &Path) -> bool {
    run_dir.join(DIR).join(MANIFEST).is_file() || run_dir.join(OLD_DIR).join(MANIFEST).is_file()
}
