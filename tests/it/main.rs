//! The cross-process tests, one program (one link) built as a test of the `actor` package, so
//! that they can start the `actor` binary; a module per subject. The chaos test is its own
//! program (tests/chaos.rs: its own main, and slow); two tests here that wait on purpose (a
//! 17 s outage, two timed `actor train` sessions) are slow too (`cargo xtask slow`).

#[path = "../support/slow.rs"]
mod slow;
#[path = "../support/mod.rs"]
mod support;

mod actor_faults;
mod demonstrators;
mod dependencies;
mod distributed;
mod resume;
mod run_map;
