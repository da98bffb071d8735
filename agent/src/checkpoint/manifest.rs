//! `manifest.json`: every file's length and 64-bit FNV-1a hash, checked before anything of a
//! checkpoint is used.

use std::fs;
use std::path::Path;

use serde::{Deserialize, Serialize};
use sim_core::hash::fnv1a64;

use super::error::CheckpointError;
use super::names::{FILES, FORMAT_VERSION, MANIFEST};

/// `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub version: u32,
    pub files: Vec<FileEntry>,
    /// The vector sensor's layout the network reads (`RunConfig::vector_layout`, e.g.
    /// `vector/1 ego:1x3 …`), for runs with `[env.vector]`; absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vector_layout: Option<String>,
}

/// One file of a manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileEntry {
    pub name: String,
    pub bytes: u64,
    /// 64-bit FNV-1a of the file's bytes, 16 lowercase hex digits.
    pub fnv1a64: String,
}

/// Just the version of a manifest, read first so that a future layout is reported as a version
/// mismatch rather than as unparsable.
#[derive(Debug, Deserialize)]
struct ManifestVersion {
    version: u32,
}

/// The manifest of files given by name and contents.
#[must_use]
pub fn manifest_of<'a>(files: impl IntoIterator<Item = (&'a str, &'a [u8])>) -> Manifest {
    Manifest {
        version: FORMAT_VERSION,
        vector_layout: None,
        files: files
            .into_iter()
            .map(|(name, bytes)| FileEntry { name: name.into(), bytes: bytes.len() as u64, fnv1a64: format!("{:016x}", fnv1a64(bytes)) })
            .collect(),
    }
}

/// Reads a checkpoint file; a missing file is [`CheckpointError::Missing`].
pub fn read_file(path: &Path) -> Result<Vec<u8>, CheckpointError> {
    fs::read(path).map_err(|source| match source.kind() {
        std::io::ErrorKind::NotFound => CheckpointError::Missing { path: path.to_owned() },
        _ => CheckpointError::Io { path: path.to_owned(), action: "reading", source },
    })
}

/// Reads and checks the manifest of `dir`: its version, and that it lists only known files, once.
fn read_manifest(dir: &Path) -> Result<Manifest, CheckpointError> {
    let manifest_path = dir.join(MANIFEST);
    let corrupt = |reason: String| CheckpointError::Corrupt { path: manifest_path.clone(), reason };
    let bytes = read_file(&manifest_path)?;
    let version: ManifestVersion = serde_json::from_slice(&bytes).map_err(|e| corrupt(format!("unparsable JSON: {e}")))?;
    if version.version != FORMAT_VERSION {
        return Err(CheckpointError::UnsupportedVersion { path: manifest_path, found: version.version });
    }
    let manifest: Manifest = serde_json::from_slice(&bytes).map_err(|e| corrupt(format!("unparsable JSON: {e}")))?;
    for (i, entry) in manifest.files.iter().enumerate() {
        if !FILES.contains(&entry.name.as_str()) {
            return Err(corrupt(format!("lists unknown file `{}`", entry.name)));
        }
        if manifest.files[..i].iter().any(|e| e.name == entry.name) {
            return Err(corrupt(format!("lists `{}` twice", entry.name)));
        }
    }
    Ok(manifest)
}

/// Checks `bytes`, read from `path`, against its manifest entry.
fn check(entry: &FileEntry, path: &Path, bytes: &[u8], manifest_path: &Path) -> Result<(), CheckpointError> {
    let expected =
        u64::from_str_radix(&entry.fnv1a64, 16).ok().filter(|_| entry.fnv1a64.len() == 16).ok_or_else(|| CheckpointError::Corrupt {
            path: manifest_path.to_owned(),
            reason: format!("hash of `{}` is not 16 hex digits: {:?}", entry.name, entry.fnv1a64),
        })?;
    let len = bytes.len() as u64;
    if len != entry.bytes {
        let reason = if len < entry.bytes {
            format!("truncated: {len} bytes, the manifest records {}", entry.bytes)
        } else {
            format!("{len} bytes, the manifest records {}", entry.bytes)
        };
        return Err(CheckpointError::Corrupt { path: path.to_owned(), reason });
    }
    let found = fnv1a64(bytes);
    if found != expected {
        return Err(CheckpointError::Corrupt {
            path: path.to_owned(),
            reason: format!("checksum mismatch (expected {expected:016x}, found {found:016x})"),
        });
    }
    Ok(())
}

/// Reads the manifest and every file it must list, checking version, lengths and hashes. Returns
/// the files' bytes in [`FILES`] order.
pub fn read_verified(dir: &Path) -> Result<[Vec<u8>; 5], CheckpointError> {
    let manifest = read_manifest(dir)?;
    let manifest_path = dir.join(MANIFEST);
    let mut out: [Vec<u8>; 5] = Default::default();
    for (name, slot) in FILES.iter().zip(&mut out) {
        let entry = manifest
            .files
            .iter()
            .find(|e| e.name == *name)
            .ok_or_else(|| CheckpointError::Corrupt { path: manifest_path.clone(), reason: format!("does not list `{name}`") })?;
        let path = dir.join(name);
        let bytes = read_file(&path)?;
        check(entry, &path, &bytes, &manifest_path)?;
        *slot = bytes;
    }
    Ok(out)
}

/// Reads some files of `dir` (paths inside it), checking each that the manifest lists. Lenient
/// where evaluation needs it: a directory without a manifest, or a file it does not list, is read
/// unchecked (a checkpoint assembled by hand from a weights file and its configuration).
pub fn read_verified_subset(dir: &Path, paths: &[&Path]) -> Result<Vec<Vec<u8>>, CheckpointError> {
    let manifest_path = dir.join(MANIFEST);
    let manifest = if manifest_path.is_file() { Some(read_manifest(dir)?) } else { None };
    let mut out = Vec::with_capacity(paths.len());
    for path in paths {
        let bytes = read_file(path)?;
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if let Some(entry) = manifest.as_ref().and_then(|m| m.files.iter().find(|e| e.name == name)) {
            check(entry, path, &bytes, &manifest_path)?;
        }
        out.push(bytes);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manifest_hashes_are_fnv1a64_in_16_hex_digits_as_on_disk() {
        // FNV-1a 64 reference vectors: manifests written before the hash moved to sim-core still verify.
        let m = manifest_of([("a", &b"a"[..]), ("foobar", &b"foobar"[..])]);
        let hashes: Vec<_> = m.files.iter().map(|e| (e.name.as_str(), e.bytes, e.fnv1a64.as_str())).collect();
        assert_eq!(hashes, [("a", 1, "af63dc4c8601ec8c"), ("foobar", 6, "85944171f73967e8")]);
    }
}
