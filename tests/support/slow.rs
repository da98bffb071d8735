//! The slow tests' gate (rust-analyzer's `skip_slow_tests()`): `cargo test --workspace` skips
//! them, each saying so; `cargo xtask slow` runs them with `HD_SLOW_TESTS=1`.

/// True, after saying so on stderr, unless `HD_SLOW_TESTS=1`: `if slow::skip() { return; }`.
#[track_caller]
pub fn skip() -> bool {
    let skip = !std::env::var("HD_SLOW_TESTS").is_ok_and(|v| v == "1");
    if skip {
        // Straight to stderr, not `eprintln!`, which the test harness keeps to itself on a pass.
        let at = std::panic::Location::caller();
        let _ = std::io::Write::write_fmt(&mut std::io::stderr(), format_args!("skipped slow test ({at}): `cargo xtask slow` runs it\n"));
    }
    skip
}
