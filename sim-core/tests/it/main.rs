//! sim-core's integration tests, one program (one link) with a module per subject.

mod common;
mod hazards;
mod map_loader;
mod opendrive;
mod planner;
mod reward_ordering;
mod sensor;
mod world;
