//! Checkpoints as files: what a checkpoint directory holds, how its integrity is checked, and how
//! a path a user gives is turned into one. The learner writes checkpoints (`learner::checkpoint`,
//! atomically); the learner's resume and the actor's evaluation read them through this module.
//!
//! A checkpoint is the directory `RUN_DIR/checkpoint/` (format version [`FORMAT_VERSION`]):
//! - `online.safetensors`, `target.safetensors`: the parameters of the two networks
//!   (`crate::weights`);
//! - `optimizer.safetensors`: Adam's moments, tensors `m.<param>` and `v.<param>`;
//! - `state.json`: the [`Counters`], Adam's step count and learning rate, the format version;
//! - `config.toml`: the run configuration it was trained with (so a checkpoint describes itself);
//! - `manifest.json`: the format version and, for every file above, its length and 64-bit FNV-1a
//!   hash.
//!
//! While a new checkpoint is swapped in, the previous one waits as `checkpoint.old/`: readers take
//! `checkpoint/`, else `checkpoint.old/` ([`locate`]).

mod error;
mod locate;
mod manifest;
mod names;
mod state;

pub use error::CheckpointError;
pub use locate::{Located, locate, resolve};
pub use manifest::{FileEntry, Manifest, manifest_of, read_file, read_verified, read_verified_subset};
pub use names::*;
pub use state::{Counters, Progress, State};
