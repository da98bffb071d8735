//! Why a plot could not be made.

use std::path::PathBuf;

use learner::telemetry::records::{EPISODES_FILE, RecordsError};

/// Why a plot could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("no run directories to plot")]
    NoRuns,
    #[error("invalid plot options: {0}")]
    Options(String),
    /// A `--run-dir` argument that is neither `DIR` nor `LABEL=DIR1,DIR2,...`.
    #[error("--run-dir `{arg}`: {reason} (expected DIR, or LABEL=DIR1,DIR2,... for one agent over several seeds)")]
    RunArg { arg: String, reason: String },
    #[error("x axis `{value}`: expected `minutes` or `env-steps`")]
    XAxis { value: String },
    #[error("run directory {} has no {EPISODES_FILE}", dir.display())]
    MissingEpisodes { dir: PathBuf },
    #[error("reading {}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Records(#[from] RecordsError),
    #[error("the embedded font could not be loaded")]
    Font,
    #[error("drawing {}: {message}", path.display())]
    Draw { path: PathBuf, message: String },
}
