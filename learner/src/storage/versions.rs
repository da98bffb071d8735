//! Weights versions that never go backwards, even across a SIGKILL and `--resume`.
//!
//! A restarted learner resumes from its last checkpoint, whose weights version is older than what
//! it had published (and what actors hold) before the crash. Versions are therefore handed out
//! from leased blocks: the file `RUN_DIR/weights-version` records, durably, the highest version
//! this run may have published (the end of the current block); a new block is recorded before
//! its first version is used. A restarted learner starts above the recorded end, so its first
//! version is newer than anything any actor can hold, and actors take its weights on their next
//! poll. The cost is one small synced write per [`BLOCK`] publications, and a jump of up to
//! `BLOCK` in the version number at a restart.

use std::fs;
use std::path::{Path, PathBuf};

/// Versions leased at a time.
pub const BLOCK: u64 = 1000;

/// The lease file's name in the run directory.
pub const FILE: &str = "weights-version";

/// Why the lease could not be read or extended.
#[derive(Debug, thiserror::Error)]
pub enum LeaseError {
    #[error("{action} {}", path.display())]
    Io {
        path: PathBuf,
        action: &'static str,
        #[source]
        source: std::io::Error,
    },
    #[error("{} does not hold a version number: {text:?}", path.display())]
    Corrupt { path: PathBuf, text: String },
}

/// Hands out increasing weights versions for one run directory.
#[derive(Debug)]
pub struct VersionLease {
    path: PathBuf,
    /// The last version handed out.
    current: u64,
    /// The end of the leased block (recorded in the file).
    leased: u64,
}

impl VersionLease {
    /// Opens the lease of `run_dir`: the first version will be above `at_least` (a checkpoint's
    /// version) and above every version a previous process of this run may have published.
    pub fn open(run_dir: &Path, at_least: u64) -> Result<Self, LeaseError> {
        let path = run_dir.join(FILE);
        let recorded = match fs::read_to_string(&path) {
            Ok(text) => text.trim().parse::<u64>().map_err(|_| LeaseError::Corrupt { path: path.clone(), text })?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => 0,
            Err(source) => return Err(LeaseError::Io { path, action: "reading", source }),
        };
        let current = recorded.max(at_least);
        Ok(Self { path, current, leased: current })
    }

    /// The last version handed out (before the first [`next_version`](Self::next_version): the floor).
    #[must_use]
    pub fn current(&self) -> u64 {
        self.current
    }

    /// The next version, newer than every version handed out in this run so far.
    pub fn next_version(&mut self) -> Result<u64, LeaseError> {
        if self.current >= self.leased {
            let end = self.current + BLOCK;
            record(&self.path, end)?;
            self.leased = end;
        }
        self.current += 1;
        Ok(self.current)
    }
}

/// Writes `end` to `path` durably and atomically.
fn record(path: &Path, end: u64) -> Result<(), LeaseError> {
    agent::atomic_write::write_atomic(path, format!("{end}\n").as_bytes(), None).map_err(|e| LeaseError::Io {
        path: e.path,
        action: e.action,
        source: e.source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_increase_across_a_crash_without_any_checkpoint() {
        let dir = tempfile::tempdir().unwrap();
        let mut a = VersionLease::open(dir.path(), 1).unwrap();
        assert_eq!(a.current(), 1);
        let published: Vec<u64> = (0..2500).map(|_| a.next_version().unwrap()).collect();
        assert!(published.windows(2).all(|w| w[0] < w[1]));
        let highest = *published.last().unwrap();
        // A crash: `a` is simply gone; the checkpoint is far behind (version 7).
        drop(a);
        let mut b = VersionLease::open(dir.path(), 7).unwrap();
        let first = b.next_version().unwrap();
        assert!(first > highest, "restarted at {first}, but {highest} was published before");
        assert!(first <= highest + BLOCK + 1, "{first}");
        // A checkpoint ahead of the file (a run directory copied without it) wins too.
        let mut c = VersionLease::open(dir.path(), 1 << 40).unwrap();
        assert_eq!(c.next_version().unwrap(), (1 << 40) + 1);
    }

    #[test]
    fn a_garbled_lease_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        fs::write(dir.path().join(FILE), "twelve").unwrap();
        let e = VersionLease::open(dir.path(), 0).unwrap_err().to_string();
        assert!(e.ends_with("weights-version does not hold a version number: \"twelve\""), "{e}");
    }
}
