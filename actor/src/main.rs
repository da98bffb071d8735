//! `actor`: the user-facing program. It trains (`actor train`), serves a learner as an actor
//! (`actor --learner ADDR`), evaluates checkpoints (`actor eval`), drives routes with the
//! reference driver or a random policy, and benchmarks the simulator.

mod eval;
mod runner;
mod sampling;
#[cfg(test)]
mod testing;
mod tools;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "actor",
    version,
    about = "Drives the simulator: as an actor of a learner (`actor --learner ADDR`), or for reference runs, recording and benchmarks.",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Learner to serve, host:port, http://host:port or https://host:port (TLS, with --tls-ca):
    /// run as an actor.
    #[arg(long)]
    learner: Option<String>,
    /// Environments this actor runs (one batched inference for all).
    #[arg(long, default_value_t = 4)]
    envs: usize,
    /// A name for this actor (it keeps its index, and so its exploration rate, across reconnects);
    /// the learner assigns the actor's id. `--id` is the old spelling.
    #[arg(long, alias = "id", value_name = "NAME")]
    name: Option<String>,
    #[command(flatten)]
    auth: proto::cli::AuthArgs,
    #[command(flatten)]
    tls: proto::cli::TlsArgs,
    /// Steps per batch sent to the learner.
    #[arg(long, default_value_t = 64)]
    batch_steps: usize,
    /// Steps kept while the learner is unreachable; beyond, the oldest are dropped and counted.
    #[arg(long, default_value_t = 10_000)]
    buffer_steps: usize,
    /// Seed of the environments and exploration.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Append a JSON line per acknowledged batch to this file (name, actor id, seq, steps,
    /// replay log position, ε): what the learner promised to keep, for audits and the chaos test.
    #[arg(long, hide = true)]
    ack_log: Option<std::path::PathBuf>,
    /// Exit at once when standard input reaches its end: `actor train` (and tests) give their
    /// actors a pipe whose other end closes when the parent dies, even by SIGKILL, so that no
    /// actor outlives the learner it was started for.
    #[arg(long, hide = true)]
    exit_with_stdin: bool,
    /// Run as a demonstrator: drive with this planner (`model-based-avoid`: the reference driver
    /// with the `astar+avoid` planner, which sees hazards; `model-based`: with plain A*), its
    /// controls mapped to the run's nearest action, and send the steps as demonstrations, which
    /// the learner keeps in a replay partition of their own (`[agent] demo_*`). It follows the
    /// run's episodes, hazards, map and observation, and needs no weights.
    #[arg(long, value_name = "DRIVER")]
    demonstrate: Option<String>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Train: a learner here and local actor processes, with live progress (Ctrl-C: checkpoint
    /// and exit; the same command resumes).
    Train(runner::TrainArgs),
    /// Drive evaluation routes with a policy and report completions, collisions and returns.
    Drive(tools::drive::DriveArgs),
    /// Evaluate checkpoints greedily on the paper's seven routes beside the model-based baseline
    /// (the paper's Table I).
    Eval(eval::EvalArgs),
    /// A checkpoint's Q values for one observation (a route's step, or a frame with its scalars),
    /// with a summary of the network's inputs: for checking a checkpoint loaded elsewhere
    /// (docs/MODEL.md).
    Predict(tools::predict::PredictArgs),
    /// A town seen whole from above and through the front camera, as PNGs (to check a map by
    /// eye).
    Picture(tools::picture::PictureArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(tools::bench::BenchCommand),
}

fn main() -> Result<()> {
    proto::program::init_logging();
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Train(args)) => proto::program::runtime()?.block_on(runner::run(&args)),
        Some(Command::Drive(args)) => tools::drive::run(&args),
        Some(Command::Eval(args)) => eval::run(&args),
        Some(Command::Predict(args)) => tools::predict::run(&args),
        Some(Command::Picture(args)) => tools::picture::run(&args),
        Some(Command::Bench(cmd)) => tools::bench::run(&cmd),
        None => {
            let Some(learner) = cli.learner else {
                anyhow::bail!(
                    "nothing to do: give --learner ADDR to run as an actor, or a subcommand (train, eval, drive, predict, picture, bench); see --help"
                );
            };
            let name = cli.name.unwrap_or_else(|| format!("{}-{}", hostname(), std::process::id()));
            let opts = sampling::ActorOptions {
                learner: proto::client::Target::new(&learner, cli.tls.files(), cli.auth.insecure_plaintext)?,
                envs: cli.envs,
                name,
                auth_token_file: cli.auth.auth_token_file,
                batch_steps: cli.batch_steps.max(1),
                buffer_steps: cli.buffer_steps.max(1),
                seed: cli.seed,
                ack_log: cli.ack_log,
                exit_with_stdin: cli.exit_with_stdin,
                demonstrate: cli.demonstrate.as_deref().map(sampling::demonstrator::Demonstrator::from_name).transpose()?,
            };
            proto::program::runtime()?.block_on(sampling::run(opts))
        }
    }
}

/// This machine's name, for default actor names.
fn hostname() -> String {
    std::fs::read_to_string("/etc/hostname").map(|s| s.trim().to_owned()).ok().filter(|s| !s.is_empty()).unwrap_or_else(|| "actor".into())
}
