//! How the project's programs start (`actor`, `learner` and the chaos test's learner process): logs
//! to stderr filtered by `RUST_LOG` (default `info`), and the two-thread tokio runtime they run on.

use std::io::IsTerminal;

/// Sends `tracing` events to stderr, filtered by `RUST_LOG` (default `info`). Colour only on a
/// terminal: logs redirected to files (`actor-K.log`) stay plain text.
pub fn init_logging() {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .init();
}

/// The multi-threaded runtime the programs run on: two workers (the training thread and the
/// network's pool have the other cores).
///
/// # Errors
/// When the runtime cannot be built (the OS refuses a thread or the I/O driver).
pub fn runtime() -> std::io::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()
}
