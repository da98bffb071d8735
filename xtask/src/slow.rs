//! The slow tests: the ones that call `slow::skip()` (tests/support/slow.rs), which
//! `cargo test --workspace` skips and `cargo xtask slow` runs. xtask/tests/slow_suite.rs checks
//! this list against the callers, both ways.
#![allow(dead_code)]

#[path = "../../tests/support/slow.rs"]
pub mod gate;

pub use gate::VAR;

/// A test target that holds slow tests.
#[derive(Debug)]
pub struct Target {
    pub package: &'static str,
    /// Its name (`cargo test --test NAME`).
    pub target: &'static str,
    /// Its file, from the repository's root.
    pub file: &'static str,
    /// Its slow tests, by name (run with `--exact`); empty for a `harness = false` target, which
    /// is one test (its `main` calls the gate).
    pub tests: &'static [&'static str],
}

/// Every slow test, by target. Each is slow because it runs for a long time on purpose: a
/// schedule of faults, or a network trained for hundreds of updates until it has learned.
pub const SUITE: &[Target] = &[
    // A learner and 3 actors under 3 minutes of faults.
    Target { package: "actor", target: "chaos", file: "tests/chaos.rs", tests: &[] },
];
