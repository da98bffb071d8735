//! Finding a checkpoint: in a run directory (the learner's resume), or from any path a user gives
//! (a run directory, a checkpoint directory, or the weights file in one).

use std::path::{Path, PathBuf};

use super::error::CheckpointError;
use super::names::{CONFIG, DIR, OLD_DIR, ONLINE};

/// The directory to load from `run_dir`: `checkpoint`, else `checkpoint.old` (left by a save that
/// was interrupted between its two renames).
pub fn locate(run_dir: &Path) -> Result<PathBuf, CheckpointError> {
    let current = run_dir.join(DIR);
    if current.is_dir() {
        return Ok(current);
    }
    let old = run_dir.join(OLD_DIR);
    if old.is_dir() {
        tracing::warn!("{} is absent (interrupted save): loading {}", current.display(), old.display());
        return Ok(old);
    }
    Err(CheckpointError::NotFound(run_dir.to_owned()))
}

/// A checkpoint found from a user's path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Located {
    /// The checkpoint directory.
    pub dir: PathBuf,
    /// The weights file to use: the given file, or the directory's `online.safetensors`.
    pub weights: PathBuf,
    /// The run directory, when the checkpoint directory sits in one.
    pub run_dir: Option<PathBuf>,
}

/// The checkpoint `path` names: a run directory (of `actor train` or `learner serve`), its
/// `checkpoint/` directory, or a `.safetensors` file in a checkpoint directory. The error says
/// what a checkpoint is when `path` is none.
pub fn resolve(path: &Path) -> Result<Located, CheckpointError> {
    let what = "expected a run directory of `actor train` or `learner serve`, its checkpoint/ directory, or the online.safetensors in it";
    let refuse = |reason: String| CheckpointError::NotACheckpoint { path: path.to_owned(), reason };
    if !path.exists() {
        return Err(refuse(format!("does not exist: no such file or directory ({what})")));
    }
    let dir = if path.is_file() {
        if path.extension().is_none_or(|e| e != "safetensors") {
            return Err(refuse(format!("is not a checkpoint: {what}")));
        }
        let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dir.join(CONFIG).is_file() {
            return Err(refuse(format!(
                "is not part of a checkpoint: {} is missing beside it (the checkpoint directory holds online.safetensors, config.toml and manifest.json)",
                dir.join(CONFIG).display()
            )));
        }
        dir.to_owned()
    } else {
        let has_weights = |d: &Path| d.join(ONLINE).is_file();
        let found = if has_weights(path) {
            Some(path.to_owned())
        } else {
            [DIR, OLD_DIR].into_iter().map(|sub| (sub, path.join(sub))).find(|(_, d)| has_weights(d)).map(|(sub, d)| {
                if sub == OLD_DIR {
                    tracing::warn!("{} has only {} (an interrupted save): using it", path.display(), d.display());
                }
                d
            })
        };
        found.ok_or_else(|| {
            refuse(format!("is not a checkpoint: it holds neither online.safetensors nor checkpoint/online.safetensors ({what})"))
        })?
    };
    let weights = if path.is_file() { path.to_owned() } else { dir.join(ONLINE) };
    let run_dir = dir.file_name().filter(|n| *n == DIR || *n == OLD_DIR).and_then(|_| dir.parent()).map(Path::to_owned);
    Ok(Located { dir, weights, run_dir })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_directory_its_checkpoint_and_its_weights_file_name_the_same_checkpoint() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        let ck = run.join(DIR);
        std::fs::create_dir_all(&ck).unwrap();
        for f in [ONLINE, CONFIG] {
            std::fs::write(ck.join(f), b"x").unwrap();
        }
        for p in [run.clone(), ck.clone(), ck.join(ONLINE)] {
            let l = resolve(&p).unwrap();
            assert_eq!(
                (l.dir.as_path(), l.weights.as_path(), l.run_dir.as_deref()),
                (ck.as_path(), ck.join(ONLINE).as_path(), Some(run.as_path()))
            );
        }
        let e = resolve(&tmp.path().join("nothing")).unwrap_err().to_string();
        assert!(e.contains("no such file or directory"), "{e}");
        let e = resolve(tmp.path()).unwrap_err().to_string();
        assert!(e.contains("holds neither online.safetensors"), "{e}");
        assert_eq!(locate(&run).unwrap(), ck);
        assert!(matches!(locate(tmp.path()), Err(CheckpointError::NotFound(_))));
    }
}
