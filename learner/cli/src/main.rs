//! `learner`: the training service and its tools.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};
use learner::serve::{ServeOptions, serve};
use learner_cli::{health, status};

#[derive(Debug, Parser)]
#[command(name = "learner", version, about = "The DQN training service: replay, training, checkpoints, weights for actors, status.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the training service until Ctrl-C or SIGTERM (then write a checkpoint and exit).
    Serve {
        /// Run configuration (TOML with [env], [agent], [service]); defaults when omitted.
        #[arg(long)]
        config: Option<PathBuf>,
        /// gRPC listen address, host:port (overrides service.listen; port 0 picks a free one,
        /// written to RUN_DIR/server.addr).
        #[arg(long)]
        listen: Option<String>,
        /// Run directory for the effective config, checkpoints and metrics (overrides
        /// service.run_dir).
        #[arg(long)]
        run_dir: Option<PathBuf>,
        /// Continue the run in --run-dir from its checkpoint: same counters, weights and optimizer.
        #[arg(long)]
        resume: bool,
        /// With --resume, when the replay log cannot be read whole (a record out of order or that
        /// does not decode): keep every batch before the damage and set the rest aside in
        /// RUN_DIR/replay-log.damaged/ (without it, such a log is refused with what it would drop).
        #[arg(long, requires = "resume")]
        truncate_log: bool,
        /// Serve Prometheus metrics at this address, host:port (a bare PORT is 127.0.0.1:PORT);
        /// over TLS, with the same certificates, when TLS is on.
        #[arg(long)]
        metrics_listen: Option<String>,
        /// Require this shared token (first line of the file) from every client.
        #[arg(long)]
        auth_token_file: Option<PathBuf>,
        /// Serve TLS with this PEM certificate (with --tls-key; overrides service.tls_cert). Re-read
        /// on SIGHUP and when it changes.
        #[arg(long, value_name = "FILE", requires = "tls_key")]
        tls_cert: Option<PathBuf>,
        /// The PEM private key of --tls-cert (overrides service.tls_key).
        #[arg(long, value_name = "FILE", requires = "tls_cert")]
        tls_key: Option<PathBuf>,
        /// Mutual TLS: clients must present a certificate signed by this PEM CA (overrides
        /// service.tls_client_ca).
        #[arg(long, value_name = "FILE")]
        tls_client_ca: Option<PathBuf>,
    },
    /// Write certificates for TLS and mutual TLS into DIR: a CA (ca.pem, ca-key.pem; kept when
    /// DIR has one, so running it again renews the others under the same CA), a server
    /// certificate for --hosts (server.pem, server-key.pem) and a client certificate (client.pem,
    /// client-key.pem). Keys are written with mode 0600.
    Certs {
        /// Directory to write into (created if missing).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// Host names and IP addresses the server certificate is valid for, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "localhost,127.0.0.1")]
        hosts: Vec<String>,
        /// Days the server and client certificates are valid (the CA: 10 years).
        #[arg(long, default_value_t = 365)]
        days: i64,
    },
    /// Print a learner's status: give its address, or the run directory of a learner on this
    /// machine (`learner serve --run-dir DIR` or `actor train --run-dir DIR`, which write the
    /// address they listen on to DIR/server.addr).
    #[command(group = clap::ArgGroup::new("target").required(true).args(["addr", "run_dir"]))]
    Status {
        /// The learner's address, host:port or http://host:port.
        #[arg(long)]
        addr: Option<String>,
        /// A local run directory: the address is read from DIR/server.addr.
        #[arg(long, value_name = "DIR")]
        run_dir: Option<PathBuf>,
        /// Print one JSON object on the last line of stdout.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        auth: proto::cli::AuthArgs,
        #[command(flatten)]
        tls: proto::cli::TlsArgs,
    },
    /// Check a learner through the standard gRPC health service (grpc.health.v1): exit 0 only when
    /// it reports SERVING. For container health checks; needs no token.
    Health {
        /// The learner's address, host:port or http://host:port.
        #[arg(long)]
        addr: String,
        /// Service to ask about (empty: the server as a whole; `hybriddrive.v1.Learner`: the learner).
        #[arg(long, default_value = "")]
        service: String,
        /// Seconds to wait for the connection, and again for the answer.
        #[arg(long, default_value_t = 3.0)]
        timeout: f64,
        #[command(flatten)]
        tls: proto::cli::TlsArgs,
    },
    /// Draw learning curves of run directories into a PNG, panels stacked on one x axis: the
    /// smoothed episode return, the loss, the mean Q and (with `eval.jsonl`) the periodic greedy
    /// evaluations. Each run is resampled onto a grid of 200 points across the x range, so lines
    /// are continuous where there is data and break where a run has none. One agent over several
    /// seeds (`--run-dir LABEL=DIR1,DIR2,...`) is one colour: the mean over its seeds with a shaded
    /// band from their minimum to their maximum.
    Plot {
        /// `DIR`: one run, one line (named after the directory). `LABEL=DIR1,DIR2,...`: one agent
        /// over several seeds, one line (the mean, with a min–max band) named "LABEL (N seeds)".
        /// Repeat for several lines on one chart; the forms mix. Write `./a=b` for a directory whose
        /// name contains `=`.
        #[arg(long = "run-dir", required = true, value_name = "DIR|LABEL=DIR,...", value_parser = learner_cli::plot::RunGroup::parse)]
        run_dirs: Vec<learner_cli::plot::RunGroup>,
        /// Output PNG file.
        #[arg(long)]
        out: PathBuf,
        /// The x axis of every panel: `minutes` (of training, summed over resumes) or `env-steps`.
        #[arg(long = "x", value_name = "AXIS", default_value = "minutes", value_parser = learner_cli::plot::XAxis::parse)]
        x: learner_cli::plot::XAxis,
        /// Moving-average window of the return, in episodes (widened to all the episodes of a grid
        /// cell, 1/199 of the x range, when that holds more).
        #[arg(long, default_value_t = 50)]
        smoothing: usize,
    },
    /// Print the effective configuration as TOML with a comment on every field (meaning, unit,
    /// default): the defaults, or FILE completed with defaults and validated (a starting point
    /// for `serve --config`).
    Config {
        /// A configuration file to validate and complete.
        #[arg(long, conflicts_with = "preset")]
        config: Option<PathBuf>,
        /// A named preset instead: `paper` (the paper's hybrid agent, every extension off),
        /// `end-to-end` (its baseline: no d input, no r_w), `hybrid-tuned` (`paper` with a 48x48
        /// camera, double DQN, 3-step returns, target copies every 250 updates, ε decayed over
        /// 100k steps, and the planner's signed path features as inputs), `end-to-end-tuned`
        /// (`end-to-end` with the same tuning), `hybrid-hazards` (`hybrid-tuned` with the full27
        /// actions, the progress reward, the hazard suite's episodes with hazards in half of them,
        /// and a 64x64 60° camera stacking 4 frames), `hybrid-vector` (`hybrid-hazards` with the
        /// vector sensor instead of the camera: an MLP, batches of 256, replay ratio 8) or
        /// `e2e-vector` (`hybrid-vector` without the planner). Files can start from one with
        /// `preset = "NAME"`.
        #[arg(long, value_name = "NAME")]
        preset: Option<String>,
    },
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Debug, Subcommand)]
enum BenchCommand {
    /// Times full DQN updates of the paper network (or of a vector input's multilayer
    /// perceptron) and forward passes at batch 1 and --forward-batch (medians), each also as a
    /// fraction of the machine's GEMM peak, measured in the same run. docs/PERFORMANCE.md lists
    /// the JSON fields.
    Train {
        /// Input: an image WIDTHxHEIGHTxCHANNELS (with the paper's 2 scalar inputs), or
        /// vector:N, the multilayer perceptron over N values.
        #[arg(long, default_value = "84x84x3", value_parser = learner_cli::bench::parse_input, conflicts_with = "preset")]
        input: learner_cli::bench::Input,
        /// A named preset's network (`net_shape()`), batch size and agent settings instead of
        /// --input (see `learner config --preset`).
        #[arg(long, value_name = "NAME")]
        preset: Option<String>,
        /// Actions (the Q head's outputs) of an --input network.
        #[arg(long, default_value_t = 6, conflicts_with = "preset")]
        actions: usize,
        /// Transitions per update (default: the preset's batch size, else 32).
        #[arg(long)]
        batch: Option<usize>,
        /// Images per forward pass for `forward_ms_per_sample` (an actor's batch).
        #[arg(long, default_value_t = 8)]
        forward_batch: usize,
        /// Updates to time (after one warm-up update).
        #[arg(long, default_value_t = 10)]
        updates: usize,
        /// Threads (default: every core).
        #[arg(long)]
        threads: Option<usize>,
        /// Also time candle's own network on the same update, in the same run (`--reference` is
        /// the old spelling).
        #[arg(long, alias = "reference")]
        candle: bool,
        /// Arithmetic: f32, bf16 (AMX or AVX512-BF16), both (alternating, in one process), or auto
        /// (what `[agent] precision = "auto"` runs here).
        #[arg(long, default_value = "auto", value_parser = ["auto", "f32", "bf16", "both"])]
        precision: String,
        /// Print one JSON object on the last line of stdout.
        #[arg(long)]
        json: bool,
    },
    /// The whole training loop: a learner in this process and N actor processes beside it,
    /// measured for --seconds (env steps and updates per second, samples trained per env step,
    /// weight lag, the learner's idle time, the arithmetic as a fraction of the machine's peak).
    /// The run configuration is the default one, or --preset's or --config's, with the options
    /// below applied to it. `e2e` is the old name.
    #[command(alias = "e2e")]
    Loop {
        /// Actor processes (the `actor` program next to this one).
        #[arg(long, default_value_t = 2)]
        actors: usize,
        /// Environments per actor.
        #[arg(long, default_value_t = 4)]
        envs: usize,
        /// Seconds to measure (after every actor has started streaming).
        #[arg(long, default_value_t = 30.0)]
        seconds: f64,
        /// Ingest only, no training: the actors' own rate.
        #[arg(long)]
        no_train: bool,
        /// A named run configuration (as `learner config --preset` lists them, e.g. `paper`,
        /// `hybrid-tuned`) instead of the default one.
        #[arg(long, value_name = "NAME", conflicts_with = "config")]
        preset: Option<String>,
        /// A run configuration file (TOML, as `learner serve --config` takes; it may start from a
        /// preset with `preset = "NAME"`) instead of the default one.
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// `[agent] replay_ratio`: samples trained per env step the learner allows (the JSON's
        /// `effective_replay_ratio` is what it achieved). Default: the configuration's.
        #[arg(long, value_name = "R")]
        replay_ratio: Option<f32>,
        /// `ack` (batches acknowledged once in the replay log on disk) or `none`. Default: the
        /// configuration's `[service] durability` (`ack` unless it says otherwise).
        #[arg(long, value_parser = parse_durability)]
        durability: Option<agent::config::Durability>,
        /// The run's `[agent] precision`: auto, f32 or bf16 (AMX or AVX512-BF16). Default: the
        /// configuration's (`auto` unless it says otherwise).
        #[arg(long)]
        precision: Option<agent::fastnet::Precision>,
        /// Print one JSON object on the last line of stdout.
        #[arg(long)]
        json: bool,
    },
    /// Transitions per second an in-process learner accepts over gRPC on loopback (84×84 gray
    /// frames), per durability mode.
    Ingest {
        /// Seconds to stream (per durability mode).
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// `ack`, `none`, or `both` (none, then ack, in the same run: the cost of durability).
        #[arg(long, default_value = "ack")]
        durability: String,
        /// Serve and stream over mutual TLS (certificates made for the run): the cost of TLS.
        #[arg(long)]
        tls: bool,
        /// Instead: N actors, each on its own connection, against a learner that trains (its
        /// default configuration), with the replay ratio's hold on and then off: Status latency
        /// (p50/p99, polled every 100 ms) and transitions stored per second.
        #[arg(long, value_name = "N")]
        actors: Option<usize>,
        /// Print one JSON object on the last line of stdout.
        #[arg(long)]
        json: bool,
    },
}

/// `ack` or `none` (`service.durability`).
fn parse_durability(s: &str) -> Result<agent::config::Durability, String> {
    match s {
        "ack" => Ok(agent::config::Durability::Ack),
        "none" => Ok(agent::config::Durability::None),
        other => Err(format!("`{other}`: expected ack or none")),
    }
}

/// Prints a benchmark result: JSON on the last line, or readable `key: value` lines.
fn print_result(v: &serde_json::Value, json: bool) {
    if json {
        println!("{v}");
    } else if let Some(map) = v.as_object() {
        for (k, x) in map {
            println!("{k}: {x}");
        }
    }
}

/// A plotted run: "NAME: E episodes, T training records" and what its evaluations showed.
fn run_line(r: &learner_cli::plot::RunSummary) -> String {
    let group = if r.group != r.name { format!(" [{}]", r.group) } else { String::new() };
    let mut line = format!("{}{group}: {} episodes, {} training records", r.name, r.episodes, r.train_points);
    if r.eval_points > 0 {
        line += &format!(", {} evaluations", r.eval_points);
        match r.minutes_to_competence {
            Some(m) => line += &format!(", competent ({}+ of 7 route types) after {m:.1} min", learner_cli::plot::COMPETENT_ROUTE_TYPES),
            None => line += ", not competent yet",
        }
    }
    line
}

/// A plotted group of several runs: its seeds' mean final return and time to competence.
fn group_line(g: &learner_cli::plot::GroupSummary) -> String {
    let mut line = format!("{} ({} seeds):", g.label, g.runs);
    match g.mean_final_smoothed_return {
        Some(v) => line += &format!(" final smoothed return {v:.2} (mean over seeds)"),
        None => line += " no episodes",
    }
    line += &format!(", competent in {} of {} seeds", g.competent_runs, g.runs);
    if let Some(m) = g.mean_minutes_to_competence {
        line += &format!(" (after {m:.1} min on average)");
    }
    line
}

fn main() -> Result<()> {
    proto::program::init_logging();
    let cli = Cli::parse();
    let rt = proto::program::runtime()?;
    rt.block_on(async move {
        match cli.command {
            Command::Serve { config, listen, run_dir, resume, truncate_log, metrics_listen, auth_token_file, tls_cert, tls_key, tls_client_ca } => {
                serve(ServeOptions {
                    config,
                    listen,
                    run_dir,
                    resume,
                    truncate_log,
                    metrics_listen,
                    auth_token_file,
                    tls_cert,
                    tls_key,
                    tls_client_ca,
                    extra_services: Some(learner_cli::reflection::routes()?),
                })
                .await
            }
            Command::Certs { out, hosts, days } => {
                for path in learner_cli::certs::write_set(&out, &hosts, days)? {
                    println!("wrote {}", path.display());
                }
                println!(
                    "serve: learner serve --tls-cert {dir}/server.pem --tls-key {dir}/server-key.pem --tls-client-ca {dir}/ca.pem",
                    dir = out.display()
                );
                println!(
                    "connect: actor --learner https://HOST:PORT --tls-ca {dir}/ca.pem --tls-cert {dir}/client.pem --tls-key {dir}/client-key.pem",
                    dir = out.display()
                );
                Ok(())
            }
            Command::Status { addr, run_dir, json, auth, tls } => {
                let (addr, from) = match (addr, run_dir) {
                    (Some(addr), _) => (addr, None),
                    (None, Some(dir)) => (status::addr_from_run_dir(&dir)?, Some(dir)),
                    (None, None) => unreachable!("clap requires --addr or --run-dir"),
                };
                let (target, token) = auth.target(&addr, &tls).await?;
                let mut client = match proto::client::connect_to(&target, token).await {
                    Ok(c) => c,
                    Err(e) => match from {
                        Some(dir) => {
                            return Err(anyhow::Error::new(e).context(format!(
                                "no learner answers at {addr}, the address in {}: is the run still going?",
                                dir.join(learner::serve::ADDR_FILE).display()
                            )));
                        }
                        None => return Err(e.into()),
                    },
                };
                let s = client
                    .status(proto::v1::StatusRequest {})
                    .await
                    .map_err(|e| anyhow::anyhow!("status from {addr}: {}", e.message()))?
                    .into_inner();
                if json {
                    println!("{}", status::to_json(&s));
                } else {
                    status::print_table(&s);
                }
                Ok(())
            }
            Command::Health { addr, service, timeout, tls } => {
                if !(timeout > 0.0 && timeout.is_finite()) {
                    anyhow::bail!("--timeout must be a positive number of seconds, not {timeout}");
                }
                health::check(&tls.target(&addr)?, &service, std::time::Duration::from_secs_f64(timeout)).await?;
                println!("SERVING");
                Ok(())
            }
            Command::Config { config, preset } => {
                let cfg = match (config, preset) {
                    (Some(p), _) => agent::config::RunConfig::load(&p)?,
                    (None, Some(name)) => agent::config::RunConfig::preset(&name).map_err(|e| anyhow::anyhow!("--preset: {e}"))?,
                    (None, None) => agent::config::RunConfig::default(),
                };
                print!("{}", agent::config_docs::commented_toml(&cfg));
                Ok(())
            }
            Command::Plot { run_dirs, out, x, smoothing } => {
                if smoothing == 0 {
                    anyhow::bail!("--smoothing must be at least 1 episode");
                }
                let opts = learner_cli::plot::PlotOptions { smoothing, x, ..learner_cli::plot::PlotOptions::default() };
                let summary = learner_cli::plot::plot_groups(&run_dirs, &out, &opts)?;
                for r in &summary.runs {
                    println!("{}", run_line(r));
                }
                for g in summary.groups.iter().filter(|g| g.runs > 1) {
                    println!("{}", group_line(g));
                }
                if !summary.hazard_kinds.is_empty() {
                    println!("hazard panels: {}", summary.hazard_kinds.join(", "));
                }
                println!("wrote {}", out.display());
                Ok(())
            }
            Command::Bench(BenchCommand::Train { input, preset, actions, batch, forward_batch, updates, threads, candle, precision, json }) => {
                if batch == Some(0) || forward_batch == 0 || updates == 0 || threads == Some(0) || actions == 0 {
                    anyhow::bail!("--batch, --forward-batch, --updates, --threads and --actions must be at least 1");
                }
                let (shape, agent, label) = match preset {
                    Some(name) => {
                        let cfg = agent::config::RunConfig::preset(&name).map_err(|e| anyhow::anyhow!("--preset: {e}"))?;
                        (cfg.net_shape(), cfg.agent, format!("preset:{name}"))
                    }
                    None => {
                        let agent = agent::config::AgentConfig::default();
                        (input.shape(actions, &agent), agent, input.to_string())
                    }
                };
                let batch = batch.unwrap_or(if label.starts_with("preset:") { agent.batch_size } else { 32 });
                let threads = threads.unwrap_or_else(agent::fastnet::default_threads);
                use agent::fastnet::Precision;
                let precisions = match precision.as_str() {
                    "both" => vec![Precision::F32, Precision::Bf16],
                    one => vec![one.parse::<Precision>().map_err(anyhow::Error::msg)?],
                };
                let v = tokio::task::spawn_blocking(move || {
                    learner_cli::bench::train(shape, &label, &agent, batch, forward_batch, updates, threads, candle, &precisions)
                })
                .await??;
                print_result(&v, json);
                Ok(())
            }
            Command::Bench(BenchCommand::Loop {
                actors,
                envs,
                seconds,
                no_train,
                preset,
                config,
                replay_ratio,
                durability,
                precision,
                json,
            }) => {
                if actors == 0 || envs == 0 || !(seconds > 0.0 && seconds.is_finite()) {
                    anyhow::bail!("--actors and --envs must be at least 1 and --seconds positive");
                }
                let cfg = learner_cli::bench::loop_config(
                    preset.as_deref(),
                    config.as_deref(),
                    durability,
                    precision,
                    replay_ratio,
                    !no_train,
                )?;
                let v = learner_cli::bench::whole_loop(actors, envs, seconds, !no_train, cfg).await?;
                print_result(&v, json);
                Ok(())
            }
            Command::Bench(BenchCommand::Ingest { seconds, durability, tls, actors, json }) => {
                if !(seconds > 0.0 && seconds.is_finite()) {
                    anyhow::bail!("--seconds must be a positive number, not {seconds}");
                }
                use agent::config::Durability;
                if let Some(n) = actors {
                    if n == 0 || tls || durability == "both" {
                        anyhow::bail!("--actors {n}: at least 1, without --tls, with --durability ack or none");
                    }
                    let durability = parse_durability(&durability).map_err(anyhow::Error::msg)?;
                    let v = learner_cli::bench::many_actors(n, seconds, durability).await?;
                    print_result(&v, json);
                    return Ok(());
                }
                let modes = match durability.as_str() {
                    "both" => vec![Durability::None, Durability::Ack],
                    other => vec![parse_durability(other).map_err(anyhow::Error::msg)?],
                };
                let v = learner_cli::bench::ingest(seconds, &modes, tls).await?;
                print_result(&v, json);
                Ok(())
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bench_loop(args: &[&str]) -> Result<BenchCommand, clap::Error> {
        let cli = Cli::try_parse_from(["learner", "bench", "loop"].iter().chain(args))?;
        match cli.command {
            Command::Bench(b) => Ok(b),
            other => panic!("parsed as {other:?}"),
        }
    }

    #[test]
    fn bench_loop_takes_a_preset_or_a_config_and_a_replay_ratio() {
        let BenchCommand::Loop { preset, config, replay_ratio, durability, precision, .. } =
            bench_loop(&["--preset", "hybrid-vector", "--actors", "1", "--replay-ratio", "1", "--seconds", "20", "--json"]).unwrap()
        else {
            panic!("not bench loop")
        };
        assert_eq!((preset.as_deref(), config, replay_ratio), (Some("hybrid-vector"), None, Some(1.0)));
        assert_eq!((durability, precision), (None, None), "the configuration's unless given");
        let BenchCommand::Loop { config, preset, durability, precision, .. } =
            bench_loop(&["--config", "run.toml", "--durability", "none", "--precision", "f32"]).unwrap()
        else {
            panic!("not bench loop")
        };
        assert_eq!((config, preset), (Some(PathBuf::from("run.toml")), None));
        assert_eq!((durability, precision), (Some(agent::config::Durability::None), Some(agent::fastnet::Precision::F32)));
        let both = bench_loop(&["--preset", "paper", "--config", "run.toml"]).unwrap_err();
        assert_eq!(both.kind(), clap::error::ErrorKind::ArgumentConflict);
        assert!(bench_loop(&["--replay-ratio", "lots"]).is_err());
    }
}
