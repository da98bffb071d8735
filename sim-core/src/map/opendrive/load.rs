//! `Map::from_opendrive`: XML → records (`parse.rs`) → the map (`build.rs`).

use super::build::build;
use super::error::OpenDriveError;
use super::parse::parse;
use crate::map::Map;

impl Map {
    /// Imports an OpenDRIVE (`.xodr`) road network. What it approximates or ignores is in the
    /// map's `warnings`; what it cannot import is an error naming the element's line and column.
    /// Never panics, whatever the input.
    pub fn from_opendrive(xml: &str) -> Result<Self, OpenDriveError> {
        build(parse(xml)?)
    }
}
