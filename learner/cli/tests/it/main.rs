//! learner/cli's integration tests, one program (one link) with a module per subject.

mod plot;
mod reflection;
mod tls;
