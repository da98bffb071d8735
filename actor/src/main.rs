//! `actor`: the user-facing simulator program. It drives routes with the reference driver or a
//! random policy and benchmarks the simulator; later it also streams experience to a learner.

mod bench;
mod drive;
mod policy;
mod record;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(name = "actor", version, about = "Drives the simulator: reference runs, evaluation and benchmarks.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Drive evaluation routes with a policy and report completions, collisions and returns.
    Drive(drive::DriveArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .init();
    match Cli::parse().command {
        Command::Drive(args) => drive::run(&args),
        Command::Bench(cmd) => bench::run(&cmd),
    }
}
