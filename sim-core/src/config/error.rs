//! [`ConfigError`]: a configuration value out of range, named by its dotted field path.
//!
//! A leaf of its own so that every configured part (reward, camera, the environment) can report
//! errors without importing the configuration that gathers them.

/// A configuration value that is out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("config field `{field}`: {message}")]
pub struct ConfigError {
    /// Dotted path of the field, e.g. `reward.d0`.
    pub field: String,
    pub message: String,
}
