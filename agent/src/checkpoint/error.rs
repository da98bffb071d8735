//! Why a checkpoint could not be written or read. Every variant names the file or directory.

use std::path::PathBuf;

use super::names::{DIR, FORMAT_VERSION, OLD_DIR};

#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error("no checkpoint in {} (neither {DIR}/ nor {OLD_DIR}/)", .0.display())]
    NotFound(PathBuf),
    /// A path given as a checkpoint is none (`reason` says why, e.g. "is not a checkpoint: …").
    #[error("{} {reason}", path.display())]
    NotACheckpoint { path: PathBuf, reason: String },
    #[error("checkpoint {}: {action}: {source}", path.display())]
    Io {
        path: PathBuf,
        action: &'static str,
        #[source]
        source: std::io::Error,
    },
    #[error("checkpoint {} is missing", path.display())]
    Missing { path: PathBuf },
    #[error("checkpoint {} is corrupt: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    #[error("checkpoint {} has format version {found}; this build reads version {FORMAT_VERSION}", path.display())]
    UnsupportedVersion { path: PathBuf, found: u32 },
    #[error("checkpoint {} does not fit this network: {reason}", path.display())]
    Incompatible { path: PathBuf, reason: String },
    #[error("checkpoint {}: serialising: {reason}", path.display())]
    Serialise { path: PathBuf, reason: String },
}
