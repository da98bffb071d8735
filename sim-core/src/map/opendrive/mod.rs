//! OpenDRIVE (`.xodr`) import: `parse.rs` reads the XML into checked records, `geometry.rs`
//! evaluates the plan view and the cubic records, `lanes.rs` samples lane sections across,
//! `build.rs` makes the simulator's map of them, `load.rs` runs the steps (`Map::from_opendrive`).

mod build;
mod error;
pub mod geometry;
mod lanes;
mod load;
pub mod parse;

pub use error::OpenDriveError;
