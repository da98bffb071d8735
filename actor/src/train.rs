//! `actor train`: the main job in one command. A learner in this process and local actor
//! processes (this same program with `--learner`) over loopback gRPC, with live progress. The run
//! directory is resumed when it already holds a checkpoint; Ctrl-C writes a checkpoint and exits.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Args;
use learner::serve::{ServeOptions, shutdown_signal, start};

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Run configuration (TOML; see `learner config`). Defaults when omitted.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Run directory: config, checkpoints, metrics, actor logs. Resumed if it holds a checkpoint.
    #[arg(long, default_value = "runs/train")]
    pub run_dir: PathBuf,
    /// Local actor processes.
    #[arg(long, default_value_t = 2)]
    pub actors: usize,
    /// Environments per actor.
    #[arg(long, default_value_t = 4)]
    pub envs: usize,
}

pub async fn run(args: &TrainArgs) -> Result<()> {
    if args.actors == 0 || args.actors > 64 {
        anyhow::bail!("--actors {} must be 1..=64", args.actors);
    }
    let resume = args.run_dir.join("checkpoint").exists() || args.run_dir.join("checkpoint.old").exists();
    if resume {
        eprintln!("resuming the run in {}", args.run_dir.display());
    }
    let running = start(ServeOptions {
        config: if resume { None } else { args.config.clone() },
        listen: Some("127.0.0.1:0".into()),
        run_dir: Some(args.run_dir.clone()),
        resume,
        ..ServeOptions::default()
    })
    .await?;
    let addr = running.addr.to_string();
    eprintln!(
        "learner on {addr}, run {} in {}; starting {} actors × {} environments (logs: {}/actor-N.log)",
        running.shared.run_id,
        args.run_dir.display(),
        args.actors,
        args.envs,
        args.run_dir.display()
    );
    eprintln!("Ctrl-C stops: a checkpoint is written and the same command resumes.");
    let exe = std::env::current_exe().context("locating this program to start actors")?;
    let mut children: Vec<Child> = Vec::new();
    for k in 0..args.actors {
        let log = std::fs::File::create(args.run_dir.join(format!("actor-{k}.log")))?;
        let child = Command::new(&exe)
            .args(["--learner", &addr, "--envs", &args.envs.to_string(), "--id", &format!("local-{k}"), "--seed", &k.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .with_context(|| format!("starting actor {k} ({})", exe.display()))?;
        children.push(child);
    }

    let shared = running.shared.clone();
    let progress = tokio::spawn(async move {
        let start = Instant::now();
        loop {
            tokio::time::sleep(Duration::from_secs(2)).await;
            let s = learner::service::status(&shared);
            let ep = s.episodes.unwrap_or_default();
            let connected = s.actors.iter().filter(|a| a.connected).count();
            eprintln!(
                "[{:>6.0}s] env steps {:>8}  ({:>5.0}/s)  episodes {:>6}  mean return {:>7.2}  completed {:>3.0}%  updates {:>6} ({:.2}/s)  weights v{}  replay {}  actors {}",
                start.elapsed().as_secs_f64(),
                s.transitions_received,
                s.env_steps_per_sec,
                ep.episodes_total,
                ep.mean_return,
                100.0 * ep.completion_rate,
                s.learner_step,
                s.updates_per_sec,
                s.weights_version,
                s.replay_size,
                connected
            );
        }
    });

    shutdown_signal().await;
    progress.abort();
    eprintln!("stopping: actors flush, the learner writes a checkpoint…");
    // Actors in the terminal's process group got the Ctrl-C too; make sure of it for SIGTERM.
    for c in &children {
        let _ = Command::new("kill").args(["-TERM", &c.id().to_string()]).status();
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    for c in &mut children {
        while c.try_wait()?.is_none() && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        if c.try_wait()?.is_none() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
    let path = running.stop().await?;
    eprintln!("checkpoint written to {}; run the same command to continue.", path.display());
    Ok(())
}
