//! The chaos test: a learner and 3 actors as processes, faults on a seeded schedule, invariants
//! checked throughout and at the end.
//!
//! Faults: SIGKILL of the learner and a restart with `--resume`; SIGKILL of an actor and a
//! restart under its name; SIGSTOP of an actor for 20 s, then SIGCONT; an oversized and a garbage
//! stream from a raw client. Invariants:
//! - every batch an actor saw acknowledged (its `--ack-log`) is in the learner's replay log at the
//!   position the acknowledgement named, or in a segment deleted because all its transitions had
//!   left the replay (counted as evicted); the replay rebuilt after each SIGKILL holds what the
//!   last status before the kill showed, less at most what was in flight (one batch per actor);
//! - the learner's step never goes below the last checkpoint's, and the weights version never
//!   goes back (across restarts too);
//! - every refusal is counted (by kind) and answered with its status code;
//! - Status never says connected for an actor that is dead or stopped for longer than 10 s, and
//!   live actors show connected again once the disturbance is over;
//! - the learner's resident memory stays under the replay's byte cap plus a stated overhead, and
//!   the replay log under twice the cap plus two segments;
//! - an actor restarted under its name explores, from its first batch, at no more than the
//!   schedule's ε for the run's step when it restarted plus one batch's worth (not from the start
//!   of the schedule);
//! - no panic in any log.
//!
//! A summary line gives the figures. A test of the `actor` package (so that it can start the
//! `actor` binary) with its own `main` (`harness = false`): the learner process is this same
//! program, started with `CHAOS_LEARNER=1`. A slow test: skipped unless `HD_SLOW_TESTS=1`
//! (`cargo xtask slow`). Duration: `--minutes N` (`HD_SLOW_TESTS=1 cargo test -p actor --test
//! chaos -- --minutes 30`) or `CHAOS_MINUTES`; default 3. Seed: `--seed S` or `CHAOS_SEED`.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use proto::v1 as pb;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[path = "support/slow.rs"]
mod slow;

const ACTORS: usize = 3;
/// The replay's byte cap (the smallest allowed): eviction happens during the test.
const REPLAY_MAX_BYTES: u64 = 1 << 20;
/// What the learner process may hold besides its replay: code, runtime, network buffers, the
/// network and its optimizer, weights copies (measured at ~40 MiB for this debug build).
const MEMORY_OVERHEAD: u64 = 256 << 20;
const SEGMENT_BYTES: u64 = 64 << 10;
/// Longest an actor that is dead or stopped may still be shown connected.
const DETECTION_LIMIT: Duration = Duration::from_secs(10);
const ACTOR_TIMEOUT_SECS: u64 = 5;
const STOP_SECS: u64 = 20;

fn main() -> ExitCode {
    if std::env::var_os("CHAOS_LEARNER").is_some() {
        return learner_process();
    }
    let args: Vec<String> = std::env::args().collect();
    if args.iter().any(|a| a == "--list") {
        println!("chaos: test");
        return ExitCode::SUCCESS;
    }
    // Minutes of faults: a slow test (`cargo xtask slow`).
    if slow::skip() {
        return ExitCode::SUCCESS;
    }
    let flag = |name: &str, env: &str| {
        args.iter().position(|a| a == name).and_then(|i| args.get(i + 1).cloned()).or_else(|| std::env::var(env).ok())
    };
    let minutes: f64 = flag("--minutes", "CHAOS_MINUTES").map_or(3.0, |m| m.parse().expect("--minutes N"));
    let seed: u64 = flag("--seed", "CHAOS_SEED").map_or(1, |s| s.parse().expect("--seed S"));
    let rt = proto::program::runtime().unwrap();
    match rt.block_on(run(minutes, seed)) {
        Ok(summary) => {
            println!("{summary}");
            println!("test chaos ... ok");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("chaos test FAILED: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The learner process: `learner serve` on the configuration in `CHAOS_CONFIG`.
fn learner_process() -> ExitCode {
    // stderr is learner.log here: no colour.
    proto::program::init_logging();
    let opts = learner::serve::ServeOptions {
        config: std::env::var_os("CHAOS_CONFIG").map(PathBuf::from),
        resume: std::env::var_os("CHAOS_RESUME").is_some(),
        ..Default::default()
    };
    let rt = proto::program::runtime().unwrap();
    match rt.block_on(learner::serve::serve(opts)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("learner: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The processes and what the test knows about them.
struct World {
    dir: PathBuf,
    addr: String,
    learner: Child,
    actors: Vec<ActorProc>,
    /// Figures for the summary and the invariants.
    learner_restarts: u32,
    faults: u32,
    max_detection: Duration,
    max_weights_delay: Duration,
    max_rss: u64,
    max_log_bytes: u64,
    refusals: u32,
    highest_version: u64,
    highest_step_seen: u64,
    /// Actor restarts to check ε for: (actor, its ack log's lines before the restart, the
    /// schedule's ε at the run's step then).
    restarts: Vec<(usize, usize, f64)>,
}

struct ActorProc {
    name: String,
    child: Option<Child>,
    stopped: bool,
    /// Since when it is dead or stopped (status must stop calling it connected), or alive again
    /// (status must call it connected once it has had time to reconnect).
    since: Instant,
}

impl ActorProc {
    fn live(&self) -> bool {
        self.child.is_some() && !self.stopped
    }
}

fn config(dir: &Path, addr: &str) -> RunConfig {
    let mut cfg = RunConfig::tiny(&dir.join("run"));
    cfg.env.traffic.vehicles = 3;
    let a = &mut cfg.agent;
    (a.min_replay, a.replay_capacity, a.replay_max_bytes, a.replay_ratio) = (64, 3000, REPLAY_MAX_BYTES, 0.5);
    let s = &mut cfg.service;
    s.listen = addr.into();
    s.checkpoint_interval_secs = 10;
    s.actor_timeout_secs = ACTOR_TIMEOUT_SECS;
    s.replay_log_segment_bytes = SEGMENT_BYTES;
    s.max_message_bytes = 1 << 20;
    cfg
}

fn frame_bytes() -> usize {
    16 * 16
}

fn free_port() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().to_string()
}

fn append_log(path: &Path) -> std::fs::File {
    std::fs::OpenOptions::new().create(true).append(true).open(path).unwrap()
}

fn spawn_learner(dir: &Path, resume: bool) -> Child {
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.env("CHAOS_LEARNER", "1").env("CHAOS_CONFIG", dir.join("chaos.toml")).env("RUST_LOG", "info");
    if resume {
        cmd.env("CHAOS_RESUME", "1");
    }
    cmd.stdout(Stdio::null()).stderr(append_log(&dir.join("learner.log"))).spawn().unwrap()
}

fn spawn_actor(dir: &Path, addr: &str, k: usize) -> Child {
    let name = format!("chaos-{k}");
    Command::new(env!("CARGO_BIN_EXE_actor"))
        .args(["--learner", addr, "--envs", "2", "--name", &name, "--batch-steps", "16", "--seed", &k.to_string()])
        .arg("--ack-log")
        .arg(dir.join(format!("acks-{k}.jsonl")))
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(append_log(&dir.join(format!("actor-{k}.log"))))
        .spawn()
        .unwrap()
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill").args([&format!("-{sig}"), &child.id().to_string()]).status().map(|s| s.success()).unwrap_or(false);
    assert!(ok, "kill -{sig} {}", child.id());
}

async fn status(addr: &str) -> Option<pb::StatusResponse> {
    let mut c = tokio::time::timeout(Duration::from_secs(3), proto::client::connect(addr, None)).await.ok()?.ok()?;
    tokio::time::timeout(Duration::from_secs(3), c.status(pb::StatusRequest {})).await.ok()?.ok().map(tonic::Response::into_inner)
}

fn rss_bytes(pid: u32) -> Option<u64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = text.lines().find(|l| l.starts_with("VmRSS:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// The learner step of the checkpoint on disk (the last durable point).
fn checkpoint_step(dir: &Path) -> u64 {
    let state = ["checkpoint", "checkpoint.old"].iter().find_map(|d| std::fs::read(dir.join("run").join(d).join("state.json")).ok());
    state.map_or(0, |s| agent::checkpoint::Progress::from_state_json(&s).learner_step.unwrap_or(0))
}

impl World {
    /// One look at the learner: the invariants that hold at any moment.
    async fn probe(&mut self) -> anyhow::Result<Option<pb::StatusResponse>> {
        let Some(s) = status(&self.addr).await else { return Ok(None) };
        anyhow::ensure!(s.training_error.is_empty(), "training stopped: {}", s.training_error);
        anyhow::ensure!(
            s.weights_version >= self.highest_version,
            "weights version went back from {} to {}",
            self.highest_version,
            s.weights_version
        );
        self.highest_version = s.weights_version;
        self.highest_step_seen = self.highest_step_seen.max(s.learner_step);
        if let Some(rss) = rss_bytes(self.learner.id()) {
            self.max_rss = self.max_rss.max(rss);
            anyhow::ensure!(
                rss <= REPLAY_MAX_BYTES + MEMORY_OVERHEAD,
                "learner resident memory {rss} bytes is over the replay cap + overhead"
            );
        }
        self.max_log_bytes = self.max_log_bytes.max(s.replay_log_bytes);
        anyhow::ensure!(
            s.replay_log_bytes <= 2 * REPLAY_MAX_BYTES + 2 * SEGMENT_BYTES,
            "replay log of {} bytes: not bounded by the replay",
            s.replay_log_bytes
        );
        for a in &self.actors {
            let shown = s.actors.iter().find(|r| r.name == a.name).is_some_and(|r| r.connected);
            let quiet = a.since.elapsed();
            if !a.live() && shown {
                self.max_detection = self.max_detection.max(quiet);
                anyhow::ensure!(
                    quiet <= DETECTION_LIMIT,
                    "{} has been dead or stopped for {quiet:?}, and Status still says connected",
                    a.name
                );
            }
        }
        Ok(Some(s))
    }

    /// Probes every second for `secs`, and checks at the end that every live actor shows
    /// connected (`settle`: the disturbance is over).
    async fn watch(&mut self, secs: f64, settle: bool) -> anyhow::Result<Option<pb::StatusResponse>> {
        let end = Instant::now() + Duration::from_secs_f64(secs);
        let mut last = None;
        while Instant::now() < end {
            if let Some(s) = self.probe().await? {
                last = Some(s);
            }
            tokio::time::sleep(Duration::from_secs(1)).await;
        }
        if settle {
            last = Some(self.settle().await?);
        }
        Ok(last)
    }

    /// Waits (at most 90 s) until every live actor shows connected and streams.
    async fn settle(&mut self) -> anyhow::Result<pb::StatusResponse> {
        let deadline = Instant::now() + Duration::from_secs(90);
        loop {
            if let Some(s) = self.probe().await? {
                let missing: Vec<&str> = self
                    .actors
                    .iter()
                    .filter(|a| a.live() && !s.actors.iter().any(|r| r.name == a.name && r.connected && r.transitions > 0))
                    .map(|a| a.name.as_str())
                    .collect();
                if missing.is_empty() {
                    return Ok(s);
                }
                anyhow::ensure!(Instant::now() < deadline, "live actors {missing:?} not connected and streaming within 90 s: {s:#?}");
            } else {
                anyhow::ensure!(Instant::now() < deadline, "the learner does not answer");
            }
            tokio::time::sleep(Duration::from_millis(500)).await;
        }
    }

    async fn kill_learner(&mut self, rng: &mut ChaCha8Rng) -> anyhow::Result<()> {
        let before = self.probe().await?.ok_or_else(|| anyhow::anyhow!("no status before the kill"))?;
        self.learner.kill()?;
        self.learner.wait()?;
        let durable_step = checkpoint_step(&self.dir);
        tokio::time::sleep(Duration::from_secs_f64(rng.random_range(0.5..3.0))).await;
        self.learner = spawn_learner(&self.dir, true);
        self.learner_restarts += 1;
        let deadline = Instant::now() + Duration::from_secs(60);
        let after = loop {
            if let Some(s) = self.probe().await? {
                break s;
            }
            anyhow::ensure!(Instant::now() < deadline, "the learner did not come back with --resume");
            tokio::time::sleep(Duration::from_millis(200)).await;
        };
        anyhow::ensure!(after.run_id == before.run_id, "another run after --resume");
        anyhow::ensure!(after.learner_step >= durable_step, "learner step {} is below the checkpoint's {durable_step}", after.learner_step);
        // One batch per actor may have been stored but not yet durable (and so not acknowledged).
        let in_flight = (ACTORS * 16) as u64;
        anyhow::ensure!(
            after.replay_size + in_flight >= before.replay_size,
            "the rebuilt replay holds {} transitions; {} before the kill",
            after.replay_size,
            before.replay_size
        );
        // Actors get the new process's weights on their next poll.
        let first_version = after.weights_version;
        let restarted = Instant::now();
        loop {
            let s = self.settle().await?;
            let behind: Vec<&str> = self
                .actors
                .iter()
                .filter(|a| a.live())
                .filter(|a| s.actors.iter().find(|r| r.name == a.name).is_none_or(|r| r.weights_version < first_version))
                .map(|a| a.name.as_str())
                .collect();
            if behind.is_empty() {
                self.max_weights_delay = self.max_weights_delay.max(restarted.elapsed());
                break;
            }
            anyhow::ensure!(restarted.elapsed() < Duration::from_secs(90), "{behind:?} did not take the restarted learner's weights");
            tokio::time::sleep(Duration::from_millis(250)).await;
        }
        println!(
            "[chaos] learner SIGKILLed and resumed: replay {} → {}, step {} (checkpoint {durable_step}), version {} → {}",
            before.replay_size, after.replay_size, after.learner_step, before.weights_version, after.weights_version
        );
        Ok(())
    }

    async fn kill_actor(&mut self, k: usize, rng: &mut ChaCha8Rng) -> anyhow::Result<()> {
        let a = &mut self.actors[k];
        let mut child = a.child.take().expect("live");
        let killed = child.kill();
        child.wait()?;
        killed?;
        a.since = Instant::now();
        println!("[chaos] {} SIGKILLed", a.name);
        let wait = rng.random_range(3.0..8.0);
        self.watch(wait, false).await?;
        if let Some(s) = status(&self.addr).await {
            let acked = std::fs::read_to_string(self.dir.join(format!("acks-{k}.jsonl"))).unwrap_or_default().lines().count();
            self.restarts.push((k, acked, s.epsilon));
        }
        let a = &mut self.actors[k];
        a.child = Some(spawn_actor(&self.dir, &self.addr, k));
        a.since = Instant::now();
        Ok(())
    }

    async fn stop_actor(&mut self, k: usize) -> anyhow::Result<()> {
        let a = &mut self.actors[k];
        signal(a.child.as_ref().expect("live"), "STOP");
        a.stopped = true;
        a.since = Instant::now();
        println!("[chaos] {} SIGSTOPped for {STOP_SECS} s", a.name);
        self.watch(STOP_SECS as f64, false).await?;
        let a = &mut self.actors[k];
        signal(a.child.as_ref().expect("live"), "CONT");
        a.stopped = false;
        a.since = Instant::now();
        Ok(())
    }

    /// An oversized and a garbage stream from a raw client: each answered with its code, counted
    /// by kind.
    async fn bad_stream(&mut self, garbage: bool) -> anyhow::Result<()> {
        let Some(before) = self.probe().await? else { return Ok(()) };
        let message = if garbage { vec![0xff; 100] } else { vec![0u8; 2 << 20] };
        let code = match raw_stream(&self.addr, message).await {
            Err(status) => status.code(),
            Ok(()) => anyhow::bail!("a {} stream ended with OK", if garbage { "garbage" } else { "oversized" }),
        };
        let expected = if garbage { tonic::Code::InvalidArgument } else { tonic::Code::ResourceExhausted };
        anyhow::ensure!(code == expected, "a {} stream ended with {code:?}", if garbage { "garbage" } else { "oversized" });
        let after = self.probe().await?.ok_or_else(|| anyhow::anyhow!("no status after a refusal"))?;
        let (kind_before, kind_after) = if garbage {
            (before.streams_refused_undecodable, after.streams_refused_undecodable)
        } else {
            (before.streams_refused_too_large, after.streams_refused_too_large)
        };
        anyhow::ensure!(
            kind_after == kind_before + 1 && after.batches_rejected > before.batches_rejected,
            "the refusal was not counted: {before:?} → {after:?}"
        );
        self.refusals += 1;
        println!("[chaos] {} stream refused with {code:?} and counted", if garbage { "garbage" } else { "oversized" });
        Ok(())
    }
}

/// One raw message on `StreamExperience`, from a client that never registered.
async fn raw_stream(addr: &str, message: Vec<u8>) -> Result<(), tonic::Status> {
    let channel = tonic::transport::Endpoint::from_shared(format!("http://{addr}"))
        .map_err(|e| tonic::Status::internal(e.to_string()))?
        .connect()
        .await
        .map_err(|e| tonic::Status::unavailable(e.to_string()))?;
    proto::raw::stream_experience(channel, None, vec![message]).await.map(drop)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    KillLearner,
    KillActor,
    StopActor,
    Oversized,
    Garbage,
}

async fn run(minutes: f64, seed: u64) -> anyhow::Result<String> {
    let tmp = tempfile::tempdir()?;
    let dir = tmp.path().to_path_buf();
    let addr = free_port();
    std::fs::write(dir.join("chaos.toml"), config(&dir, &addr).to_toml())?;
    println!("[chaos] seed {seed}, {minutes} min of faults, in {}", dir.display());
    let learner = spawn_learner(&dir, false);
    let actors = (0..ACTORS)
        .map(|k| ActorProc { name: format!("chaos-{k}"), child: Some(spawn_actor(&dir, &addr, k)), stopped: false, since: Instant::now() })
        .collect();
    let mut w = World {
        dir: dir.clone(),
        addr: addr.clone(),
        learner,
        actors,
        learner_restarts: 0,
        faults: 0,
        max_detection: Duration::ZERO,
        max_weights_delay: Duration::ZERO,
        max_rss: 0,
        max_log_bytes: 0,
        refusals: 0,
        highest_version: 0,
        highest_step_seen: 0,
        restarts: Vec::new(),
    };
    let result = schedule(&mut w, minutes, seed).await;
    // Whatever happened: no process outlives the test.
    for a in &mut w.actors {
        if let Some(c) = a.child.as_mut() {
            if a.stopped {
                let _ = Command::new("kill").args(["-CONT", &c.id().to_string()]).status();
            }
            let _ = c.kill();
            let _ = c.wait();
        }
    }
    let _ = w.learner.kill();
    let _ = w.learner.wait();
    if result.is_err() {
        // Kept for a look at the logs.
        eprintln!("[chaos] logs kept in {}", tmp.keep().display());
    }
    result
}

async fn schedule(w: &mut World, minutes: f64, seed: u64) -> anyhow::Result<String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Start: every actor streams and training publishes weights.
    let s = w.settle().await?;
    let deadline = Instant::now() + Duration::from_secs(120);
    while w.probe().await?.is_none_or(|s| s.weights_version < 3) {
        anyhow::ensure!(Instant::now() < deadline, "no training within 120 s: {s:#?}");
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
    println!("[chaos] {} actors streaming, training; faults begin", ACTORS);

    let end = Instant::now() + Duration::from_secs_f64(minutes * 60.0);
    let mut bag: Vec<Fault> = Vec::new();
    while Instant::now() < end {
        if bag.is_empty() {
            // Every kind of fault in each round, in a seeded order.
            bag = vec![Fault::KillLearner, Fault::KillActor, Fault::StopActor, Fault::Oversized, Fault::Garbage];
            for i in (1..bag.len()).rev() {
                bag.swap(i, rng.random_range(0..=i));
            }
        }
        let fault = bag.pop().expect("refilled");
        let k = rng.random_range(0..ACTORS);
        w.faults += 1;
        match fault {
            Fault::KillLearner => w.kill_learner(&mut rng).await?,
            Fault::KillActor => w.kill_actor(k, &mut rng).await?,
            Fault::StopActor => w.stop_actor(k).await?,
            Fault::Oversized => w.bad_stream(false).await?,
            Fault::Garbage => w.bad_stream(true).await?,
        }
        let pause = rng.random_range(4.0..10.0);
        w.watch(pause, true).await?;
    }

    // The end: actors stop (flushing what they can), the learner is SIGKILLed one last time, and
    // every acknowledged batch is looked up in its replay log.
    let last = w.settle().await?;
    for a in &mut w.actors {
        if let Some(c) = a.child.as_mut() {
            signal(c, "TERM");
        }
    }
    for a in &mut w.actors {
        if let Some(mut c) = a.child.take() {
            let code = c.wait()?;
            anyhow::ensure!(code.success(), "{} exited with {code:?} after SIGTERM", a.name);
        }
    }
    let final_status = w.probe().await?.unwrap_or(last);
    w.learner.kill()?;
    w.learner.wait()?;
    let (acked, lost, evicted) = audit(&w.dir)?;
    // Resumed once more: the replay is rebuilt, and stops cleanly.
    w.learner = spawn_learner(&w.dir, true);
    let deadline = Instant::now() + Duration::from_secs(60);
    let resumed = loop {
        if let Some(s) = status(&w.addr).await {
            break s;
        }
        anyhow::ensure!(Instant::now() < deadline, "the learner did not resume after the last kill");
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    anyhow::ensure!(
        resumed.replay_size + (ACTORS * 16) as u64 >= final_status.replay_size,
        "replay {} after the last resume, {} before",
        resumed.replay_size,
        final_status.replay_size
    );
    signal(&w.learner, "TERM");
    let code = w.learner.wait()?;
    anyhow::ensure!(code.success(), "the learner exited with {code:?} after SIGTERM");

    // No panic anywhere.
    for entry in std::fs::read_dir(&w.dir)? {
        let path = entry?.path();
        if path.extension().is_some_and(|e| e == "log") {
            let text = std::fs::read_to_string(&path)?;
            anyhow::ensure!(!text.contains("panicked"), "a panic in {}:\n{text}", path.display());
        }
    }
    let learner_log = std::fs::read_to_string(w.dir.join("learner.log"))?;
    anyhow::ensure!(learner_log.contains("experience stream refused"), "the refusals were not logged");

    anyhow::ensure!(lost == 0, "{lost} acknowledged transitions are not in the replay log");
    let excess = restarted_exploration(w)?;
    Ok(format!(
        "chaos summary: faults injected {}, transitions acknowledged {acked}, lost {lost}, learner restarts {}, max detection delay {:.1} s \
         (evicted {evicted}, refusals {}, max weights delay after a restart {:.1} s, max learner RSS {:.0} MiB, max replay log {:.2} MiB, \
         last step {}, last version {}, max ε above the schedule after an actor restart {excess:.5}, seed {seed})",
        w.faults,
        w.learner_restarts,
        w.max_detection.as_secs_f64(),
        w.refusals,
        w.max_weights_delay.as_secs_f64(),
        w.max_rss as f64 / (1 << 20) as f64,
        w.max_log_bytes as f64 / (1 << 20) as f64,
        w.highest_step_seen,
        w.highest_version,
    ))
}

/// Every acknowledged batch against the replay log: (transitions acknowledged, lost, evicted).
fn restarted_exploration(w: &World) -> anyhow::Result<f64> {
    // One batch's worth of the schedule: the actors send 16 steps per batch.
    let a = &config(&w.dir, &w.addr).agent;
    let batch = 16.0 * f64::from(a.epsilon_start - a.epsilon_end) / a.epsilon_decay_steps as f64;
    let mut max_excess = 0f64;
    for &(k, before, schedule) in &w.restarts {
        let text = std::fs::read_to_string(w.dir.join(format!("acks-{k}.jsonl")))?;
        let Some(line) = text.lines().nth(before) else { continue };
        let v: serde_json::Value = serde_json::from_str(line)?;
        let eps = v["epsilon"].as_f64().unwrap_or(f64::NAN);
        let excess = eps - schedule;
        max_excess = max_excess.max(excess);
        anyhow::ensure!(
            excess <= batch + 1e-6,
            "chaos-{k} explored at ε = {eps:.4} in its first batch after a restart; the schedule was at {schedule:.4} for the run's step"
        );
    }
    Ok(max_excess)
}

fn audit(dir: &Path) -> anyhow::Result<(u64, u64, u64)> {
    let (entries, first) =
        learner::storage::replay_log::inventory(&dir.join("run"), learner::storage::replay_log::StepShape::frames(frame_bytes()))?;
    let by_position: BTreeMap<u64, &learner::storage::replay_log::Entry> = entries.iter().map(|e| (e.position, e)).collect();
    let (mut acked, mut lost, mut evicted) = (0u64, 0u64, 0u64);
    for k in 0..ACTORS {
        let path = dir.join(format!("acks-{k}.jsonl"));
        let Ok(f) = std::fs::File::open(&path) else { continue };
        for line in BufReader::new(f).lines() {
            let v: serde_json::Value = serde_json::from_str(&line?)?;
            let (position, stored, steps) =
                (v["log_position"].as_u64().unwrap_or(0), v["stored"].as_u64().unwrap_or(0), v["steps"].as_u64().unwrap_or(0));
            let actor = v["actor_id"].as_str().unwrap_or("");
            acked += stored;
            anyhow::ensure!(position > 0, "an acknowledgement without a log position: {v}");
            if position < first {
                evicted += stored;
                continue;
            }
            match by_position.get(&position) {
                Some(e) if e.actor == actor && e.steps as u64 == steps => {}
                other => {
                    eprintln!("[chaos] LOST: {v} (log holds {other:?})");
                    lost += stored;
                }
            }
        }
    }
    Ok((acked, lost, evicted))
}
