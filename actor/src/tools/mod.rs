//! The commands that help a person look at the simulator and at checkpoints, apart from training
//! and evaluation: `actor drive`, `record` (through `drive --record`), `picture`, `predict` and
//! `bench`.

pub mod bench;
pub mod drive;
pub mod picture;
pub mod predict;
pub mod record;
