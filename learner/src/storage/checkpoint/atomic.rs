//! The file-system steps that make a save atomic and durable: writing with fsync, fsyncing a
//! directory's entries, swapping a complete directory in by renames, and tidying what a crashed
//! save left.

use std::fs;
use std::io::Write;
use std::path::Path;

use agent::checkpoint::{CheckpointError, DIR, OLD_DIR, TMP_PREFIX};

/// Swaps the complete directory `tmp` in as `run_dir/checkpoint`.
pub fn swap_in(run_dir: &Path, tmp: &Path) -> Result<(), CheckpointError> {
    let current = run_dir.join(DIR);
    let old = run_dir.join(OLD_DIR);
    if current.is_dir() {
        if old.exists() {
            // Stale (a crash after the swap): `checkpoint` is complete, so this can go.
            fs::remove_dir_all(&old).map_err(io_error(&old, "removing a stale previous checkpoint"))?;
        }
        fs::rename(&current, &old).map_err(io_error(&current, "moving the previous checkpoint aside"))?;
    }
    fs::rename(tmp, &current).map_err(io_error(tmp, "renaming the new checkpoint into place"))?;
    sync_dir(run_dir)
}

/// Removes the temporary directories of other processes' interrupted saves.
pub fn remove_stale_temporaries(run_dir: &Path, pid: u32) {
    let Ok(entries) = fs::read_dir(run_dir) else { return };
    let ours = format!("{TMP_PREFIX}{pid}-");
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(TMP_PREFIX)
            && !name.starts_with(&ours)
            && entry.path().is_dir()
            && let Err(e) = fs::remove_dir_all(entry.path())
        {
            tracing::warn!("removing the stale {}: {e}", entry.path().display());
        }
    }
}

pub fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), CheckpointError> {
    let mut f = fs::File::create(path).map_err(io_error(path, "creating"))?;
    f.write_all(bytes).map_err(io_error(path, "writing"))?;
    f.sync_all().map_err(io_error(path, "syncing"))
}

/// Makes a directory's entries (creations, renames) durable. A no-op where directories cannot be
/// opened as files.
pub fn sync_dir(path: &Path) -> Result<(), CheckpointError> {
    #[cfg(unix)]
    fs::File::open(path).and_then(|d| d.sync_all()).map_err(io_error(path, "syncing the directory"))?;
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

pub fn io_error(path: &Path, action: &'static str) -> impl Fn(std::io::Error) -> CheckpointError + use<> {
    let path = path.to_owned();
    move |source| CheckpointError::Io { path: path.clone(), action, source }
}
