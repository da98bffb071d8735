//! One owner per run directory (PostgreSQL's `postmaster.pid`, LevelDB's `LOCK`): a process that
//! writes a run — `learner serve`, `actor train` — holds an exclusive lock on `RUN_DIR/LOCK` for
//! its whole life, taken before it reads anything. A second one on the same directory is refused
//! at once with the holder's PID, host and start time. The lock is the operating system's
//! (`flock`), so it goes with its holder, also after a SIGKILL: `--resume` then needs no manual
//! step. Read-only commands (`learner status`, `learner plot`, `actor eval`) take no lock.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// The lock file's name in a run directory.
pub const LOCK_FILE: &str = "LOCK";

/// Why a run directory could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum RunLockError {
    #[error(
        "run directory {dir} is in use by another process ({holder}): one learner or `actor train` per run directory; \
         stop it first, or choose another --run-dir"
    )]
    Held { dir: PathBuf, holder: String },
    #[error("locking run directory {dir} ({path}): {source}")]
    Io { dir: PathBuf, path: PathBuf, source: std::io::Error },
}

/// The exclusive lock on a run directory, held until dropped.
#[derive(Debug)]
pub struct RunLock {
    file: File,
    path: PathBuf,
}

impl Drop for RunLock {
    /// Unlocks explicitly rather than by closing: a child being started at that moment (between
    /// its fork and its exec, which closes the descriptor) shares the lock's open file, and the
    /// lock would outlive this holder until it execs.
    fn drop(&mut self) {
        let _ = self.file.unlock();
    }
}

impl RunLock {
    /// Locks `dir` (which must exist) for this process, recording who holds it.
    pub fn acquire(dir: &Path) -> Result<Self, RunLockError> {
        let path = dir.join(LOCK_FILE);
        let io = |source| RunLockError::Io { dir: dir.to_owned(), path: path.clone(), source };
        let mut file = OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path).map_err(io)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                let holder = if holder.is_empty() { "a process that has not yet said who it is".to_owned() } else { holder.to_owned() };
                return Err(RunLockError::Held { dir: dir.to_owned(), holder });
            }
            Err(TryLockError::Error(e)) => return Err(io(e)),
        }
        let me = holder_line();
        file.set_len(0)
            .and_then(|()| file.rewind())
            .and_then(|()| file.write_all(me.as_bytes()))
            .and_then(|()| file.sync_all())
            .map_err(io)?;
        Ok(Self { file, path })
    }

    /// The lock file.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// "PID 123 on host h, started 2026-12-02T01:02:03Z": who holds the lock.
fn holder_line() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .map(|h| h.trim().to_owned())
        .unwrap_or_else(|_| "an unknown host".into());
    format!("PID {} on host {host}, started {}\n", std::process::id(), humantime::format_rfc3339_seconds(std::time::SystemTime::now()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_naming_the_holder_and_freed_on_drop() {
        let dir = tempfile::tempdir().unwrap();
        let first = RunLock::acquire(dir.path()).unwrap();
        let err = RunLock::acquire(dir.path()).unwrap_err().to_string();
        assert!(err.contains(&format!("PID {} on host", std::process::id())), "{err}");
        assert!(err.contains("is in use by another process"), "{err}");
        assert!(err.contains(&dir.path().display().to_string()), "{err}");
        drop(first);
        let again = RunLock::acquire(dir.path()).unwrap();
        assert_eq!(again.path(), dir.path().join(LOCK_FILE));
    }
}
