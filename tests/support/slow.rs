//! The gate of the slow tests (today the chaos test alone: the learning tests, the corridor
//! among them, finish in seconds and stay in the fast suite): `cargo test --workspace` skips them, each saying so; `cargo xtask slow` (and CI, through
//! `cargo xtask ci`) runs them with `HD_SLOW_TESTS=1`. Standard library only, so that every test
//! file can include it (`#[path = ".../tests/support/slow.rs"] mod slow;`); the list of the slow
//! tests that `cargo xtask slow` runs is xtask/src/slow.rs, checked against the callers of this file.
#![allow(dead_code)]

use std::io::Write;

/// The variable that turns the slow tests on (`1`).
pub const VAR: &str = "HD_SLOW_TESTS";

/// Whether the slow tests run (`HD_SLOW_TESTS=1`).
pub fn enabled() -> bool {
    std::env::var(VAR).is_ok_and(|v| v == "1")
}

/// Whether to skip the calling slow test: true, after saying so on the terminal, unless
/// `HD_SLOW_TESTS=1`. Call it first: `if slow::skip() { return; }`.
#[track_caller]
pub fn skip() -> bool {
    if enabled() {
        return false;
    }
    let at = std::panic::Location::caller();
    let thread = std::thread::current();
    let name = thread.name().filter(|n| *n != "main").map_or_else(String::new, |n| format!("`{n}` "));
    // Straight to stderr, not through `eprintln!`: the test harness keeps a passing test's
    // printed output to itself, and a skip must not be silent.
    let _ = writeln!(
        std::io::stderr(),
        "skipped slow test {name}({}:{}): run the slow tests with `cargo xtask slow` ({VAR}=1)",
        at.file(),
        at.line()
    );
    true
}
