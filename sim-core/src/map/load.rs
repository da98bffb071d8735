//! Loading a [`Map`]: text → [`MapSpec`](super::MapSpec) (`format.rs`) → geometry (`build.rs`).
//!
//! Kept out of `mod.rs`, which holds the map's types: the builder produces those types, so the
//! file that runs it cannot be the file that defines them without the two importing each other.

use super::format::{MapError, parse};
use super::{DEFAULT_TOWN, EMBEDDED_TOWNS, Map, build};

impl Map {
    /// Parses and builds a map from its text.
    pub fn from_text(text: &str) -> Result<Self, MapError> {
        build::build(&parse(text)?)
    }

    /// The embedded default town.
    #[must_use]
    pub fn default_town() -> Self {
        Self::from_text(DEFAULT_TOWN).expect("the embedded default town is valid (checked by tests)")
    }

    /// An embedded town by name (`default_town`, `held_out_town`); `None` for any other name.
    #[must_use]
    pub fn embedded(name: &str) -> Option<Self> {
        let (_, text) = EMBEDDED_TOWNS.iter().find(|(n, _)| *n == name)?;
        Some(Self::from_text(text).expect("the embedded towns are valid (checked by tests)"))
    }
}
