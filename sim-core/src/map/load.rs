//! Loading a [`Map`]: text → [`MapSpec`](super::MapSpec) (`format.rs`) → geometry (`build.rs`).
//!
//! Kept out of `mod.rs`, which holds the map's types: the builder produces those types, so the
//! file that runs it cannot be the file that defines them without the two importing each other.

use std::path::Path;

use super::format::{MapError, parse};
use super::opendrive::OpenDriveError;
use super::{DEFAULT_TOWN, EMBEDDED_TOWNS, Map, build};

/// A map file that could not be loaded, in either format.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapFileError {
    #[error(transparent)]
    Text(#[from] MapError),
    #[error(transparent)]
    OpenDrive(#[from] OpenDriveError),
}

impl Map {
    /// Parses and builds a map from its text.
    pub fn from_text(text: &str) -> Result<Self, MapError> {
        build::build(&parse(text)?)
    }

    /// A map file's content, in the format its name says: `.xodr` (any case) is OpenDRIVE,
    /// anything else the text format (docs/MAP-FORMAT.md). The one place the two are told apart.
    /// An OpenDRIVE map without a name in its header is named after the file.
    pub fn from_file_text(path: &Path, text: &str) -> Result<Self, MapFileError> {
        let is_xodr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("xodr"));
        if !is_xodr {
            return Ok(Self::from_text(text)?);
        }
        let mut map = Self::from_opendrive(text)?;
        if map.name == "opendrive"
            && let Some(stem) = path.file_stem().and_then(|s| s.to_str())
        {
            map.name = stem.to_owned();
        }
        Ok(map)
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
