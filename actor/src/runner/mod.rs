//! `actor train`: the main job in one command. A learner in this process and local actor
//! processes (this same program with `--learner`) over loopback gRPC, with live progress. The run
//! directory is resumed when it already holds a checkpoint; Ctrl-C writes a checkpoint and exits.
//! With `--max-minutes`, the run also stops (the same way) once its total run time — summed over
//! resumptions — reaches the budget, so an interrupted budgeted run resumes to the same budget.

pub mod best;
pub mod periodic_eval;

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use anyhow::{Context, Result};
use clap::Args;
use learner::serve::{ServeOptions, start};

use learner::telemetry::records::{EvalKindRecord, EvalRecord, EvalRouteRecord};

use crate::runner::best::Counters;
use crate::runner::periodic_eval::{PeriodicScore, SEED, score_weights};

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Run configuration (TOML; see `learner config`). Without it and without --preset, the
    /// `hybrid-tuned` preset (the configuration that learns fastest on a CPU).
    #[arg(long, conflicts_with = "preset")]
    pub config: Option<PathBuf>,
    /// Start from a named configuration instead: `hybrid-tuned` (the default: the paper's hybrid
    /// agent tuned for a short CPU budget), `paper` (the paper's hybrid agent as published),
    /// `end-to-end` (its baseline without d), `end-to-end-tuned`, `hybrid-hazards` (the tuned
    /// hybrid agent with full-authority actions, the progress reward, hazard episodes and a
    /// stacked 64x64 camera), `hybrid-vector` (the same seeing objects, rays and the planner's
    /// path as numbers instead of a camera: an MLP) or `e2e-vector` (without the planner); see
    /// `learner config --help`.
    /// A file can do the same with `preset = "NAME"`.
    #[arg(long, value_name = "NAME")]
    pub preset: Option<String>,
    /// Seed of the network initialisation and replay sampling (`agent.seed`) and of the actors'
    /// environments and exploration (actor k gets 64·S + k). Default: the configuration's seed,
    /// actors 0..N.
    #[arg(long)]
    pub seed: Option<u64>,
    /// The town to train on (`[env] map`): `default_town` (the default), `held_out_town` or a map
    /// file, the text format or OpenDRIVE `.xodr`. The learner sends its content to the actors.
    #[arg(long, value_name = "TOWN|FILE")]
    pub map: Option<String>,
    /// Stop (checkpoint written, like Ctrl-C) once the run has trained this many minutes in
    /// total, counting earlier sessions of a resumed run.
    #[arg(long, alias = "minutes", value_name = "MINUTES")]
    pub max_minutes: Option<f64>,
    /// Stop (checkpoint written, like Ctrl-C) once the run has received this many environment
    /// steps in total, counting earlier sessions: a budget that means the same on any machine
    /// (`--max-minutes` does not). With both, whichever is spent first.
    #[arg(long, value_name = "STEPS")]
    pub max_env_steps: Option<u64>,
    /// Run directory: config, checkpoints, metrics, actor logs. Resumed if it holds a checkpoint.
    #[arg(long, default_value = "runs/train")]
    pub run_dir: PathBuf,
    /// Local actor processes. One by default: on 2 cores one actor of 4 environments feeds the
    /// learner at its replay ratio, and a second takes CPU from the updates (docs/RESULTS.md).
    /// Add actors on machines with more cores.
    #[arg(long, default_value_t = 1)]
    pub actors: usize,
    /// Environments per actor.
    #[arg(long, default_value_t = 4)]
    pub envs: usize,
    /// Minutes between greedy evaluations of the current weights on the seven routes (ε = 0;
    /// with `[env.hazards] rate > 0`, on the hazard suite too), on validation seeds 10000..
    /// that `actor eval` does not use. Written to RUN_DIR/eval.jsonl (drawn by `learner plot`);
    /// the weights that score highest (mean driving score) are kept in RUN_DIR/best/, which
    /// `actor eval --checkpoint RUN_DIR/best` reads. 0 turns them off.
    #[arg(long, default_value_t = 2.0, value_name = "MINUTES")]
    pub eval_every: f64,
    /// Runs per route (and per hazard kind) of each periodic evaluation (fixed seeds, the same
    /// every time).
    #[arg(long, default_value_t = 4)]
    pub eval_runs: u32,
    /// When resuming a run whose replay log cannot be read whole (a record out of order or that
    /// does not decode): keep every batch before the damage and set the rest aside in
    /// RUN_DIR/replay-log.damaged/ (without it, such a log is refused with what it would drop).
    #[arg(long)]
    pub truncate_log: bool,
    /// Demonstrator processes started beside the learning actors (`actor --demonstrate`, with
    /// --envs environments each): they drive `--demonstrator`'s planner and their steps are kept
    /// as demonstrations (`[agent] demo_capacity`, `demo_share`, `demo_margin`; docs/TRAINING.md).
    /// With `[agent] demo_pretrain_updates` > 0 the learning actors start once pre-training is done.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub demo_actors: usize,
    /// The driver the demonstrators demonstrate with: `model-based-avoid` (sees hazards) or
    /// `model-based`.
    #[arg(long, default_value = "model-based-avoid", value_name = "DRIVER")]
    pub demonstrator: String,
}

pub async fn run(args: &TrainArgs) -> Result<()> {
    if args.actors == 0 || args.actors > 64 {
        anyhow::bail!("--actors {} must be 1..=64", args.actors);
    }
    if args.demo_actors > 64 {
        anyhow::bail!("--demo-actors {} must be 0..=64", args.demo_actors);
    }
    let demonstrator = crate::sampling::demonstrator::Demonstrator::from_name(&args.demonstrator)?;
    if !(args.eval_every.is_finite() && args.eval_every >= 0.0) || args.eval_runs == 0 {
        anyhow::bail!("--eval-every {} must be >= 0 minutes and --eval-runs {} at least 1", args.eval_every, args.eval_runs);
    }
    if let Some(m) = args.max_minutes
        && !(m.is_finite() && m > 0.0)
    {
        anyhow::bail!("--max-minutes {m} must be a positive number of minutes");
    }
    if args.max_env_steps == Some(0) {
        anyhow::bail!("--max-env-steps 0 must be a positive number of environment steps");
    }
    let resume = args.run_dir.join("checkpoint").exists() || args.run_dir.join("checkpoint.old").exists();
    let config = if resume {
        eprintln!("resuming the run in {}", args.run_dir.display());
        if args.config.is_some() || args.preset.is_some() || args.seed.is_some() || args.map.is_some() {
            eprintln!("(the run's saved configuration applies: --config, --preset, --seed and --map are ignored when resuming)");
        }
        None
    } else {
        requested_config(args)?
    };
    let running = start(ServeOptions {
        config,
        listen: Some("127.0.0.1:0".into()),
        run_dir: Some(args.run_dir.clone()),
        resume,
        truncate_log: args.truncate_log,
        ..ServeOptions::default()
    })
    .await?;
    let budget_secs = args.max_minutes.map(|m| m * 60.0);
    if let Some(b) = budget_secs {
        let used = running.shared.run_secs();
        if used >= b {
            eprintln!("the run has already trained {:.1} min, the budget of --max-minutes {:.1}: nothing to do", used / 60.0, b / 60.0);
            running.stop().await?;
            return Ok(());
        }
        eprintln!("time budget: {:.1} min in total ({:.1} min used so far); stops with a checkpoint when spent", b / 60.0, used / 60.0);
    }
    if let Some(b) = args.max_env_steps {
        let used = env_steps(&running.shared);
        if used >= b {
            eprintln!("the run has already received {used} env steps, the budget of --max-env-steps {b}: nothing to do");
            running.stop().await?;
            return Ok(());
        }
        eprintln!("step budget: {b} env steps in total ({used} so far); stops with a checkpoint when spent");
    }
    let addr = running.addr.to_string();
    eprintln!(
        "learner on {addr}, run {} in {}; starting {} × {} environments (logs: {}/actor-N.log)",
        running.shared.run_id,
        args.run_dir.display(),
        if args.actors == 1 { "1 actor".to_string() } else { format!("{} actors", args.actors) },
        args.envs,
        args.run_dir.display()
    );
    let exe = std::env::current_exe().context("locating this program to start actors")?;
    eprintln!("status, from another terminal: {}", status_command(&exe, &args.run_dir));
    eprintln!("Ctrl-C stops: a checkpoint is written and the same command resumes.");
    let mut children: Vec<Child> = Vec::new();
    let session = format!(
        "==== {} {} run {}: actor {{k}} of {}, {} environments, learner {addr} ====",
        humantime::format_rfc3339_seconds(std::time::SystemTime::now()),
        if resume { "resumed" } else { "started" },
        running.shared.run_id,
        args.actors,
        args.envs
    );
    // Demonstrators first: pre-training, when configured, needs their demonstrations before the
    // learning actors start.
    for k in 0..args.demo_actors {
        let log = open_actor_log(&args.run_dir.join(format!("demo-{k}.log")), &session.replace("actor {k}", &format!("demonstrator {k}")))?;
        // Seeds after the learning actors' (64·S + k for k < 64), so that no demonstrator drives
        // a learning actor's episodes.
        let seed = args.seed.map_or(1000 + k as u64, |s| s.wrapping_mul(64).wrapping_add(1000 + k as u64));
        let extra = ["--demonstrate", demonstrator.name()];
        let child = spawn_actor(&exe, &addr, args.envs, &format!("demo-{k}"), seed, &extra, log)
            .with_context(|| format!("starting demonstrator {k} ({})", exe.display()))?;
        children.push(child);
    }
    let mut interrupted = false;
    if args.demo_actors > 0 {
        eprintln!("{} demonstrator(s) driving `{}` (logs: {}/demo-N.log)", args.demo_actors, demonstrator.name(), args.run_dir.display());
        interrupted = tokio::select! {
            () = wait_for_pretraining(&running.shared) => false,
            () = proto::shutdown::signal() => true,
        };
    }
    for k in 0..if interrupted { 0 } else { args.actors } {
        let log = open_actor_log(&args.run_dir.join(format!("actor-{k}.log")), &session.replace("{k}", &k.to_string()))?;
        let seed = args.seed.map_or(k as u64, |s| s.wrapping_mul(64).wrapping_add(k as u64));
        let child = spawn_actor(&exe, &addr, args.envs, &format!("local-{k}"), seed, &[], log)
            .with_context(|| format!("starting actor {k} ({})", exe.display()))?;
        children.push(child);
    }

    let reporter = std::sync::Arc::new(learner::telemetry::progress::Reporter::stderr());
    let progress = tokio::spawn(learner::serve::progress_loop(running.shared.clone(), reporter.clone(), Duration::from_secs(2)));

    let evaluations = (args.eval_every > 0.0).then(|| {
        let every = Duration::from_secs_f64(args.eval_every * 60.0);
        tokio::spawn(periodic_evaluation(running.shared.clone(), args.run_dir.clone(), every, args.eval_runs, reporter.clone()))
    });

    let shared = running.shared.clone();
    let max_env_steps = args.max_env_steps;
    let budget_spent = async move {
        if budget_secs.is_none() && max_env_steps.is_none() {
            return std::future::pending().await;
        }
        loop {
            if let Some(b) = budget_secs
                && shared.run_secs() >= b
            {
                return format!("time budget of {:.1} min spent", b / 60.0);
            }
            if let Some(b) = max_env_steps
                && env_steps(&shared) >= b
            {
                return format!("step budget of {b} env steps spent");
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    };
    tokio::select! {
        () = proto::shutdown::signal(), if !interrupted => {}
        () = std::future::ready(()), if interrupted => {}
        spent = budget_spent => eprintln!("{spent}"),
        // Training died (see `learner::serve`): stop everything and exit non-zero (the stop below
        // returns the reason); the same command resumes from the last checkpoint and the replay log.
        reason = running.failed() => eprintln!("the learner stopped: {reason}"),
    }
    progress.abort();
    if let Some(e) = evaluations {
        e.abort();
    }
    reporter.finish();
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
    let s = learner::service::status(&running.shared);
    let path = running.stop().await?;
    eprintln!(
        "checkpoint written to {} ({} env steps, {} episodes, {} updates); run the same command to continue.",
        path.display(),
        s.transitions_received,
        s.episodes.unwrap_or_default().episodes_total,
        s.learner_step
    );
    Ok(())
}

/// Every `every`, drives the learner's current weights greedily on the default town's seven routes
/// (and, for a run that trains with hazards, on the hazard suite), `runs` runs each on the
/// validation seeds, records the result in `eval.jsonl` and keeps the best weights in `best/`;
/// until aborted.
async fn periodic_evaluation(
    shared: std::sync::Arc<learner::shared_state::Shared>,
    run_dir: PathBuf,
    every: Duration,
    runs: u32,
    reporter: std::sync::Arc<learner::telemetry::progress::Reporter>,
) {
    let hazards = shared.cfg.env.hazards.rate > 0.0;
    let mut best = crate::runner::best::current(&run_dir);
    loop {
        tokio::time::sleep(every).await;
        let (weights, learner_step, env_steps) = {
            let c = shared.counters.lock().expect("counters lock");
            (shared.current_weights(), c.learner_step, c.env_steps)
        };
        if learner_step == 0 {
            continue;
        }
        let (cfg, bytes, time_secs) = (shared.cfg.clone(), weights.bytes.clone(), shared.run_secs());
        let done = tokio::task::spawn_blocking(move || score_weights(&cfg, &bytes, "default_town", runs, SEED, hazards)).await;
        let score = match done {
            Ok(Ok(score)) => score,
            Ok(Err(e)) => {
                tracing::warn!("periodic evaluation failed: {e:#}");
                continue;
            }
            Err(_) => return,
        };
        let mut record = eval_record(&score, runs);
        (record.time_secs, record.env_steps, record.learner_step, record.weights_version) =
            (time_secs, env_steps, learner_step, weights.version);
        record.best = crate::runner::best::beats(score.selection_score(), best);
        let hazard_part = record.hazard_driving_score.map_or(String::new(), |h| format!(", hazards {h:.2}"));
        reporter.println(&format!(
            "[eval {:>5.1} min] greedy on the 7 routes ({runs} runs each): {}/7 route types completed in at least half their runs, {:.0}% of runs, mean return {:.1}; driving score {:.2}{hazard_part}{}",
            time_secs / 60.0,
            record.route_types_mastered,
            100.0 * record.completion_rate,
            record.mean_return,
            record.driving_score.unwrap_or_default(),
            if record.best { " (best so far: kept in best/)" } else { "" }
        ));
        if record.best {
            let saved = serde_json::to_vec_pretty(&record).map_err(anyhow::Error::from).and_then(|json| {
                crate::runner::best::save(&run_dir, &weights.bytes, &shared.cfg.to_toml(), Counters { learner_step, env_steps }, &json)
            });
            match saved {
                Ok(_) => best = Some(score.selection_score()),
                Err(e) => {
                    tracing::warn!("writing best/: {e:#}");
                    record.best = false;
                }
            }
        }
        if let Err(e) = shared.metrics.eval(&record) {
            tracing::warn!("writing eval.jsonl: {e}");
        }
    }
}

/// Waits while the learner pre-trains on demonstrations (`agent.demo_pretrain_updates`), saying
/// how far it is every 10 s; returns at once when there is none to do.
async fn wait_for_pretraining(shared: &learner::shared_state::Shared) {
    let left = || shared.stats.lock().expect("stats lock").pretrain_updates_left;
    if left() == 0 {
        return;
    }
    eprintln!("pre-training on demonstrations ({} updates) before the learning actors start", left());
    let mut said = Instant::now();
    while left() > 0 && !shared.stopping() && shared.failure().is_none() {
        if said.elapsed() >= Duration::from_secs(10) {
            let demos = shared.replay.lock().expect("replay lock").demo_len();
            eprintln!("  pre-training: {} updates left, {demos} demonstrations stored", left());
            said = Instant::now();
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// Environment steps the run has received, over all its sessions.
fn env_steps(shared: &learner::shared_state::Shared) -> u64 {
    shared.counters.lock().expect("counters lock").env_steps
}

/// The preset of `actor train` without --config or --preset: the configuration that learns fastest
/// on a CPU (docs/RESULTS.md); the paper's own is `--preset paper`.
const DEFAULT_PRESET: &str = "hybrid-tuned";

/// Opens an actor's log for appending (earlier sessions' logs are kept) and writes the session's
/// header line.
/// Starts `actor --learner ADDR` as a child named `name` (a learning actor, or a demonstrator with
/// `extra`), its log on stderr. Its standard input is a pipe this process holds: when this process
/// dies, even by SIGKILL, the pipe closes and the actor exits (`--exit-with-stdin`).
fn spawn_actor(
    exe: &std::path::Path,
    addr: &str,
    envs: usize,
    name: &str,
    seed: u64,
    extra: &[&str],
    log: std::fs::File,
) -> std::io::Result<Child> {
    Command::new(exe)
        .args(["--learner", addr, "--envs", &envs.to_string(), "--name", name, "--seed", &seed.to_string()])
        .args(extra)
        .arg("--exit-with-stdin")
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
}

fn open_actor_log(path: &std::path::Path, header: &str) -> Result<std::fs::File> {
    use std::io::Write;
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .with_context(|| format!("opening actor log {}", path.display()))?;
    writeln!(file, "{header}").with_context(|| format!("writing actor log {}", path.display()))?;
    Ok(file)
}

/// The command that prints this run's status, ready to paste in the same directory: the `learner`
/// program beside this one (`cargo build --release` builds both into target/release/), relative
/// to the working directory when it is below it, and `--run-dir`, which finds the port through
/// RUN_DIR/server.addr.
fn status_command(exe: &std::path::Path, run_dir: &std::path::Path) -> String {
    let learner = exe.with_file_name("learner");
    let program = if learner.exists() {
        let cwd = std::env::current_dir().unwrap_or_default();
        match learner.strip_prefix(&cwd) {
            Ok(rel) => format!("./{}", rel.display()),
            Err(_) => learner.display().to_string(),
        }
    } else {
        "learner".to_owned()
    };
    format!("{} status --run-dir {}", shell_word(&program), shell_word(&run_dir.display().to_string()))
}

/// `s` quoted for a POSIX shell when it needs to be.
fn shell_word(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./:=@+,".contains(c)) {
        s.to_owned()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The configuration file to start a new run with: `--config` as given, or — when `--preset` or
/// `--seed` ask for more — the effective configuration written to `RUN_DIR/requested-config.toml`.
fn requested_config(args: &TrainArgs) -> Result<Option<PathBuf>> {
    if args.config.is_some() && args.seed.is_none() && args.map.is_none() {
        return Ok(args.config.clone());
    }
    let preset = args.preset.clone().or_else(|| args.config.is_none().then(|| DEFAULT_PRESET.to_owned()));
    if args.preset.is_none() && args.config.is_none() {
        eprintln!("a new run with the `{DEFAULT_PRESET}` preset (the default; `--preset paper` trains the paper's configuration)");
    }
    let mut cfg = match (&preset, &args.config) {
        (Some(name), _) => RunConfig::preset(name).map_err(|e| anyhow::anyhow!("--preset: {e}"))?,
        (None, Some(path)) => RunConfig::load(path)?,
        (None, None) => RunConfig::default(),
    };
    if let Some(seed) = args.seed {
        cfg.agent.seed = seed;
    }
    if let Some(map) = &args.map {
        // A file by its absolute path, so that resuming from another directory finds it.
        let embedded = sim_core::map::EMBEDDED_TOWNS.iter().any(|(name, _)| name == map);
        let path = if embedded { map.clone() } else { std::path::absolute(map).map_or_else(|_| map.clone(), |p| p.display().to_string()) };
        cfg.env.map = Some(path);
    }
    std::fs::create_dir_all(&args.run_dir).with_context(|| format!("creating run directory {}", args.run_dir.display()))?;
    let path = args.run_dir.join("requested-config.toml");
    std::fs::write(&path, cfg.to_toml()).with_context(|| format!("writing {}", path.display()))?;
    Ok(Some(path))
}

/// The line of `eval.jsonl` for a periodic evaluation on the default town, without the learner's
/// counters (the caller's).
fn eval_record(score: &PeriodicScore, runs: u32) -> EvalRecord {
    EvalRecord {
        time_secs: 0.0,
        env_steps: 0,
        learner_step: 0,
        weights_version: 0,
        town: "default_town".into(),
        runs,
        route_types_mastered: score.route_types_mastered() as u32,
        mean_return: score.mean_return(),
        completion_rate: score.completion_rate(),
        routes: score
            .routes()
            .into_iter()
            .map(|(route, completed, mean_return)| EvalRouteRecord { route: route.into(), completed: completed as u32, mean_return })
            .collect(),
        driving_score: Some(score.clean.driving_score),
        hazard_driving_score: score.hazards.as_ref().map(|h| h.driving_score),
        hazard_kinds: score.hazards.as_ref().map_or_else(Vec::new, |h| {
            h.scenarios.iter().map(|s| EvalKindRecord { kind: s.scenario.into(), driving_score: s.driving_score }).collect()
        }),
        selection_score: Some(score.selection_score()),
        best: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_status_command_names_the_learner_beside_this_program_and_the_run_dir() {
        let dir = tempfile::tempdir().unwrap();
        let exe = dir.path().join("actor");
        // No learner program beside it: the bare name (on PATH, e.g. in the container image).
        assert_eq!(status_command(&exe, Path::new("runs/train")), "learner status --run-dir runs/train");
        std::fs::write(dir.path().join("learner"), b"").unwrap();
        // Beside it, outside the working directory (the temporary directory): its absolute path.
        let want = format!("{} status --run-dir runs/train", dir.path().join("learner").display());
        assert_eq!(status_command(&exe, Path::new("runs/train")), want);
        assert_eq!(status_command(Path::new("/nowhere/actor"), Path::new("my runs/a")), "learner status --run-dir 'my runs/a'");
    }

    #[test]
    fn actor_logs_are_appended_with_a_header_per_session() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("actor-0.log");
        {
            use std::io::Write;
            let mut f = open_actor_log(&path, "==== session 1 ====").unwrap();
            writeln!(f, "first session's line").unwrap();
        }
        drop(open_actor_log(&path, "==== session 2 ====").unwrap());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "==== session 1 ====\nfirst session's line\n==== session 2 ====\n");
    }

    #[test]
    fn shell_words_are_quoted_only_when_needed() {
        assert_eq!(shell_word("./target/release/learner"), "./target/release/learner");
        assert_eq!(shell_word("it's"), r"'it'\''s'");
        assert_eq!(shell_word(""), "''");
    }
}
