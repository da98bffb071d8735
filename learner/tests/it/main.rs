//! learner's integration tests, one program (one link) with a module per subject.

mod bounds;
mod corridor;
mod demonstrations;
mod metrics;
mod reliability;
mod service;
