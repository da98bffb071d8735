//! Replacing a file atomically and durably, the project's one way of doing it: the bytes go to a
//! temporary sibling, which is fsynced, renamed over the file, and the directory fsynced. A
//! reader, or the file system after a crash, sees the old file or the new one, never a part.
//! Used for the learner's version lease and certificates and the actor's evaluation reports;
//! checkpoints swap whole directories (`learner/src/checkpoint/`).

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A step of an atomic write that failed, with the path it was on.
#[derive(Debug, thiserror::Error)]
#[error("{action} {}: {source}", path.display())]
pub struct WriteError {
    pub path: PathBuf,
    /// What was being done ("writing", "syncing the directory of", …).
    pub action: &'static str,
    #[source]
    pub source: std::io::Error,
}

/// Replaces `path` with `bytes`. `mode`: the file's Unix permission bits, set before anything is
/// written (private keys: `Some(0o600)`; ignored elsewhere); `None` gives a new file
/// `File::create`'s (0o666 less the umask).
pub fn write_atomic(path: &Path, bytes: &[u8], mode: Option<u32>) -> Result<(), WriteError> {
    let err = |action: &'static str, p: &Path| {
        let p = p.to_owned();
        move |source| WriteError { path: p.clone(), action, source }
    };
    let name = path.file_name().ok_or_else(|| WriteError {
        path: path.to_owned(),
        action: "writing",
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "the path names no file"),
    })?;
    let n = TEMPORARIES.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = name.to_owned();
    tmp_name.push(format!(".tmp-{}-{n}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let result = write_synced(&tmp, bytes, mode).and_then(|()| fs::rename(&tmp, path).map_err(err("renaming into place", path)));
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result?;
    sync_parent(path)
}

fn write_synced(tmp: &Path, bytes: &[u8], mode: Option<u32>) -> Result<(), WriteError> {
    let err = |action: &'static str| {
        let p = tmp.to_owned();
        move |source| WriteError { path: p.clone(), action, source }
    };
    let mut options = fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    if let Some(mode) = mode {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(mode);
    }
    let mut f = options.open(tmp).map_err(err("creating"))?;
    #[cfg(unix)]
    if let Some(mode) = mode {
        // `open` leaves the mode of a file that already existed, and the umask narrows a new one's.
        use std::os::unix::fs::PermissionsExt;
        fs::set_permissions(tmp, fs::Permissions::from_mode(mode)).map_err(err("setting the permissions of"))?;
    }
    #[cfg(not(unix))]
    let _ = mode;
    f.write_all(bytes).map_err(err("writing"))?;
    f.sync_all().map_err(err("syncing"))
}

/// Makes the rename durable. A no-op where directories cannot be opened as files.
fn sync_parent(path: &Path) -> Result<(), WriteError> {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        fs::File::open(dir).and_then(|d| d.sync_all()).map_err(|source| WriteError {
            path: path.to_owned(),
            action: "syncing the directory of",
            source,
        })?;
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

/// Temporary files of this process, numbered so that concurrent writes of one path do not meet.
static TEMPORARIES: AtomicU64 = AtomicU64::new(0);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_the_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lease");
        write_atomic(&path, b"old", None).unwrap();
        write_atomic(&path, b"new", None).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        let names: Vec<_> = fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["lease"]);
    }

    #[cfg(unix)]
    #[test]
    fn the_mode_is_set_even_over_an_existing_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("key.pem");
        write_atomic(&path, b"a", Some(0o644)).unwrap();
        write_atomic(&path, b"b", Some(0o600)).unwrap();
        assert_eq!(fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o600);
    }

    #[test]
    fn a_failure_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing").join("report.json");
        let e = write_atomic(&path, b"x", None).unwrap_err().to_string();
        assert!(e.starts_with("creating ") && e.contains("missing/report.json.tmp-"), "{e}");
    }
}
