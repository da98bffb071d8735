//! The slow tests: the ones that call `slow::skip()` (tests/support/slow.rs), which
//! `cargo test --workspace` skips and `cargo xtask slow` runs. The tidy test checks this list
//! against the files that call the gate, both ways.

/// The variable that turns the slow tests on (`1`), as tests/support/slow.rs reads it.
pub const VAR: &str = "HD_SLOW_TESTS";

/// A test target that holds slow tests.
#[derive(Debug)]
pub struct Target {
    pub package: &'static str,
    /// Its name (`cargo test --test NAME`).
    pub target: &'static str,
    /// Its file (the one that calls the gate), from the repository's root.
    #[cfg_attr(not(test), allow(dead_code))]
    pub file: &'static str,
    /// Its slow tests, by name (run with `--exact`); empty for a `harness = false` target, which
    /// is one test (its `main` calls the gate).
    pub tests: &'static [&'static str],
}

/// Every slow test, by target. Each is slow because it runs for a long time on purpose: a
/// schedule of faults, an outage, or training sessions of a fixed time.
pub const SUITE: &[Target] = &[
    // A learner and 3 actors under 3 minutes of faults.
    Target { package: "actor", target: "chaos", file: "tests/chaos.rs", tests: &[] },
    // A learner away 17 s, for the actor's reconnect wait to grow before it returns.
    Target {
        package: "actor",
        target: "it",
        file: "tests/it/actor_faults.rs",
        tests: &["actor_faults::an_actor_registers_again_as_soon_as_a_restarted_learner_answers"],
    },
    // Two `actor train` sessions of a fixed time, for periodic evaluations and `best/`.
    Target {
        package: "actor",
        target: "it",
        file: "tests/it/resume.rs",
        tests: &["resume::actor_train_keeps_the_best_weights_of_its_periodic_evaluations_across_a_resume"],
    },
];
