//! Resume means resume: stopping and starting the learner, one actor or the whole `actor train`
//! changes nothing about what the run does next. ε follows the run's environment steps (not the
//! actor process's), a restarted actor continues with new episodes, one process owns a run
//! directory, and no actor outlives the `actor train` that started it.

use crate::support;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use support::{Process, ack_lines, actor, alive, children_of, free_port, spawn_actor, status, wait_for, wait_for_file};

/// ε decays over this many of the run's env steps, to `EPSILON_END`.
const DECAY_STEPS: u64 = 300;
const EPSILON_END: f32 = 0.05;

fn config(run_dir: &Path, listen: &str) -> RunConfig {
    let mut cfg = RunConfig::tiny(run_dir);
    cfg.env.traffic.vehicles = 2;
    cfg.agent.epsilon_decay_steps = DECAY_STEPS;
    cfg.agent.epsilon_end = EPSILON_END;
    cfg.agent.replay_capacity = 5000;
    cfg.agent.replay_ratio = 0.25;
    cfg.service.listen = listen.into();
    // Small segments, so that a log has several (the smallest size the configuration allows).
    cfg.service.replay_log_segment_bytes = 64 << 10;
    cfg
}

fn write_config(dir: &Path, listen: &str) -> std::path::PathBuf {
    let path = dir.join("run.toml");
    std::fs::write(&path, config(&dir.join("run"), listen).to_toml()).unwrap();
    path
}

async fn start_learner(dir: &Path, listen: &str, resume: bool) -> Running {
    start(ServeOptions { config: Some(write_config(dir, listen)), resume, ..ServeOptions::default() }).await.unwrap()
}

/// The ε of the first batch an actor's `--ack-log` records (waits for it).
fn first_epsilon(ack_log: &Path) -> f32 {
    wait_for_file(ack_log, 60, "a first acknowledged batch", |t| !t.is_empty() && t.ends_with('\n'));
    ack_lines(ack_log)[0]["epsilon"].as_f64().expect("epsilon in the ack log") as f32
}

/// `first_episode_seed` of an actor's log (its "environments starting" line).
fn first_episode_seed(log: &Path) -> String {
    let text = wait_for_file(log, 60, "the environments' start", |t| t.contains("first_episode_seed="));
    let at = text.find("first_episode_seed=").unwrap() + "first_episode_seed=".len();
    text[at..].split_whitespace().next().unwrap().to_owned()
}

fn actor_args(ack_log: &Path) -> Vec<String> {
    vec!["--batch-steps".into(), "16".into(), "--ack-log".into(), ack_log.display().to_string()]
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// Resumed past the end of the decay, a new actor process explores at `epsilon_end` from its first
/// batch (it used to start again at `epsilon_start`: its own step count was 0).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_resumed_run_past_its_decay_explores_at_the_schedules_end_from_the_first_batch() {
    let dir = tempfile::tempdir().unwrap();
    let addr = free_port();
    let learner = start_learner(dir.path(), &addr, false).await;
    let first = dir.path().join("ack-1.jsonl");
    let mut a = spawn_actor(&addr, "a", &strs(&actor_args(&first)), &dir.path().join("a-1.log"));
    wait_for(&addr, 120, "the run past its ε decay", |s| s.transitions_received > 2 * DECAY_STEPS).await;
    // The first life's first batch explored heavily: the schedule starts at 1.
    assert!(first_epsilon(&first) > 0.5, "{}", first_epsilon(&first));
    a.kill9();
    learner.stop().await.unwrap();

    let learner = start_learner(dir.path(), &addr, true).await;
    let second = dir.path().join("ack-2.jsonl");
    let _a = spawn_actor(&addr, "a", &strs(&actor_args(&second)), &dir.path().join("a-2.log"));
    let eps = first_epsilon(&second);
    assert!((eps - EPSILON_END).abs() < 1e-6, "the resumed actor's first batch has ε = {eps}, want {EPSILON_END}");
    let s = status(&addr).await;
    assert!((s.epsilon - f64::from(EPSILON_END)).abs() < 1e-6, "Status's schedule at the run's step: {}", s.epsilon);
    assert!((actor(&s, "a").unwrap().epsilon - EPSILON_END).abs() < 1e-6, "Status shows the actor's own ε");
    learner.stop().await.unwrap();
}

/// One actor of a running run restarts under its name: it explores at the schedule's value for the
/// run's step, not from the start, and it continues with new episodes rather than replaying its
/// first life's routes and traffic.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_actor_keeps_the_runs_schedule_and_draws_new_episodes() {
    let dir = tempfile::tempdir().unwrap();
    let addr = free_port();
    let learner = start_learner(dir.path(), &addr, false).await;
    let (log1, log2) = (dir.path().join("a-1.log"), dir.path().join("a-2.log"));
    let first = dir.path().join("ack-1.jsonl");
    let mut a = spawn_actor(&addr, "a", &strs(&actor_args(&first)), &log1);
    wait_for(&addr, 120, "the run past its ε decay", |s| s.transitions_received > 2 * DECAY_STEPS).await;
    a.kill9();
    let second = dir.path().join("ack-2.jsonl");
    let _a = spawn_actor(&addr, "a", &strs(&actor_args(&second)), &log2);
    let eps = first_epsilon(&second);
    assert!((eps - EPSILON_END).abs() < 1e-6, "the restarted actor's first batch has ε = {eps}, want {EPSILON_END}");
    let (seed1, seed2) = (first_episode_seed(&log1), first_episode_seed(&log2));
    assert_ne!(seed1, seed2, "the restarted actor replays its first life's episodes");
    assert!(std::fs::read_to_string(&log1).unwrap().contains("episode_stream=0 "), "a fresh run's first life draws stream 0");
    learner.stop().await.unwrap();
}

/// A second learner on a run directory in use is refused at once, naming the holder; the first
/// goes on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_learner_on_a_run_directory_is_refused_naming_the_holder() {
    let dir = tempfile::tempdir().unwrap();
    let addr = free_port();
    let learner = start_learner(dir.path(), &addr, false).await;
    let cfg = write_config(dir.path(), "127.0.0.1:0");
    for resume in [false, true] {
        let err = start(ServeOptions { config: Some(cfg.clone()), resume, ..ServeOptions::default() }).await.unwrap_err();
        let msg = format!("{err:#}");
        assert!(msg.contains(&format!("is in use by another process (PID {} on host", std::process::id())), "{msg}");
    }
    // The first one is untouched: it answers, and its address file is its own.
    let s = status(&addr).await;
    assert_eq!(s.run_id, learner.shared.run_id);
    assert_eq!(std::fs::read_to_string(dir.path().join("run/server.addr")).unwrap(), addr);
    learner.stop().await.unwrap();
}

fn actor_train(cfg: &Path, run_dir: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_actor"));
    c.args(["train", "--config"]).arg(cfg).arg("--run-dir").arg(run_dir).args(["--eval-every", "0", "--envs", "2"]).args(extra);
    c.env("RUST_LOG", "info");
    c
}

/// `actor train` twice on one run directory: the second refuses, naming the first; SIGKILL of the
/// first leaves no actor process behind (they watch a pipe from it), its lock goes with it, and the
/// same command resumes with every batch the learner had acknowledged.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn actor_train_owns_its_run_directory_and_its_actors_die_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_config(dir.path(), "127.0.0.1:0");
    let run_dir = dir.path().join("train");
    let mut first = Process::spawn(actor_train(&cfg, &run_dir, &[]), &dir.path().join("train-1.log"));
    let addr = wait_for_file(&run_dir.join("server.addr"), 60, "the learner's address", |t| !t.is_empty()).trim().to_owned();
    wait_for(&addr, 120, "transitions from actor train's actor", |s| s.transitions_received > 200).await;

    let second_log = dir.path().join("train-2.log");
    let mut second = Process::spawn(actor_train(&cfg, &run_dir, &[]), &second_log);
    let exit = second.wait_exit(30);
    let stderr = std::fs::read_to_string(&second_log).unwrap();
    assert!(exit.is_some_and(|e| !e.success()), "a second actor train on the same run directory ran ({exit:?}): {stderr}");
    assert!(stderr.contains(&format!("is in use by another process (PID {} on host", first.pid())), "{stderr}");
    let before = status(&addr).await;
    assert!(first.0.try_wait().unwrap().is_none(), "the first actor train stopped");

    let actors = children_of(first.pid());
    assert!(!actors.is_empty(), "actor train has no actor process");
    // Acknowledged batches are durable within milliseconds (group commit); let the last ones land.
    tokio::time::sleep(Duration::from_secs(1)).await;
    first.kill9();
    let deadline = Instant::now() + Duration::from_secs(2);
    while actors.iter().any(|&p| alive(p)) && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let left: Vec<u32> = actors.iter().copied().filter(|&p| alive(p)).collect();
    for &p in &left {
        support::signal(p, support::Signal::KILL);
    }
    assert!(left.is_empty(), "actor processes {left:?} outlived the SIGKILLed actor train by 2 s");

    // The same command resumes (the dead holder's lock is gone) with every acknowledged step.
    let resumed_log = dir.path().join("train-3.log");
    let mut resumed = Process::spawn(actor_train(&cfg, &run_dir, &["--max-env-steps", "1"]), &resumed_log);
    let exit = resumed.wait_exit(60);
    let stderr = std::fs::read_to_string(&resumed_log).unwrap();
    assert!(exit.is_some_and(|e| e.success()), "the resumed actor train ({exit:?}): {stderr}");
    assert!(stderr.contains("resuming the run"), "{stderr}");
    let at = stderr.find("the run has already received ").expect(&stderr) + "the run has already received ".len();
    let resumed: u64 = stderr[at..].split_whitespace().next().unwrap().parse().unwrap();
    assert!(resumed >= before.transitions_received, "resumed with {resumed} env steps, {} were acknowledged", before.transitions_received);
}

/// A fresh run fed by one actor until it holds `steps` env steps, then stopped (actor killed,
/// learner stopped with its final checkpoint). Returns the learner's last status.
async fn a_stopped_run(dir: &Path, steps: u64) -> proto::v1::StatusResponse {
    let addr = free_port();
    let learner = start_learner(dir, &addr, false).await;
    let mut a = spawn_actor(&addr, "a", &["--batch-steps", "16"], &dir.join("a.log"));
    wait_for(&addr, 120, "the run's steps", |s| s.transitions_received >= steps).await;
    a.kill9();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let s = status(&addr).await;
    learner.stop().await.unwrap();
    s
}

fn resume_options(dir: &Path, truncate_log: bool) -> ServeOptions {
    ServeOptions { config: Some(write_config(dir, "127.0.0.1:0")), resume: true, truncate_log, ..ServeOptions::default() }
}

/// The log's segments, oldest first.
fn segments(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> =
        std::fs::read_dir(dir.join("run").join(learner::storage::replay_log::DIR)).unwrap().map(|e| e.unwrap().path()).collect();
    v.sort();
    v
}

/// Records in a segment file.
fn records_in(path: &Path) -> u64 {
    learner::storage::replay_log::format::records(&std::fs::read(path).unwrap()).0.len() as u64
}

/// A log damaged in the middle (a segment that repeats earlier positions, as two learners writing
/// one run left it) is refused with the position and what truncating drops; `--truncate-log`
/// resumes from the intact part, dropping exactly that, and keeps the damaged part aside.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_log_damaged_in_the_middle_resumes_from_its_intact_part_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    a_stopped_run(dir.path(), 1500).await;
    let segs: Vec<_> = segments(dir.path()).into_iter().filter(|p| records_in(p) > 0).collect();
    assert!(segs.len() >= 4, "want several segments, got {segs:?}");
    let mid = segs.len() / 2;
    std::fs::copy(&segs[0], &segs[mid]).unwrap();
    let kept: u64 = segs[..mid].iter().map(|p| records_in(p)).sum();
    let dropped: u64 = segs[mid..].iter().map(|p| records_in(p)).sum();

    let err = format!("{:#}", start(resume_options(dir.path(), false)).await.unwrap_err());
    assert!(err.contains(&format!("replay log segment {} is damaged: position 1 follows {kept}", segs[mid].display())), "{err}");
    assert!(err.contains(&format!("Every batch up to position {kept} is intact")), "{err}");
    assert!(err.contains(&format!("resume again with --truncate-log: it drops the {dropped} batches")), "{err}");

    let learner = start(resume_options(dir.path(), true)).await.unwrap();
    assert_eq!(learner::service::status(&learner.shared).replay_log_first_position, 1);
    let in_log: u64 = segments(dir.path()).iter().map(|p| records_in(p)).sum();
    assert_eq!(in_log, kept, "the log keeps exactly its intact part");
    let aside = dir.path().join("run").join(learner::storage::replay_log::DAMAGED_DIR);
    assert_eq!(std::fs::read_dir(&aside).unwrap().count(), segs.len() - mid, "the damaged segments are kept aside");
    learner.stop().await.unwrap();
    // And the log reads whole from now on.
    start(resume_options(dir.path(), false)).await.unwrap().stop().await.unwrap();
}

/// The newest checkpoint's weights truncated on disk: the resume loads the previous checkpoint and
/// still counts every acknowledged step (the replay log holds them).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_truncated_newest_checkpoint_resumes_from_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    let before = a_stopped_run(dir.path(), 300).await;
    let online = dir.path().join("run/checkpoint/online.safetensors");
    let bytes = std::fs::read(&online).unwrap();
    std::fs::write(&online, &bytes[..1000]).unwrap();
    let learner = start(resume_options(dir.path(), false)).await.unwrap();
    let s = learner::service::status(&learner.shared);
    assert!(s.transitions_received >= before.transitions_received, "{} < {}", s.transitions_received, before.transitions_received);
    learner.stop().await.unwrap();
}

/// `actor train` keeps `best/`: each periodic evaluation is a line of `eval.jsonl` with its driving
/// scores (the hazard suite's too, for a run that trains with hazards); `best/` holds the weights
/// of the highest selection score so far, across a resume, and `actor eval` drives them.
#[test]
fn actor_train_keeps_the_best_weights_of_its_periodic_evaluations_across_a_resume() {
    // Slow: two `actor train` sessions of a fixed time each, for periodic evaluations to happen.
    if crate::slow::skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = config(&dir.path().join("run"), "127.0.0.1:0");
    cfg.env.hazards.rate = 0.5;
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
    let run_dir = dir.path().join("train");
    let train = |minutes: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_actor"))
            .args(["train", "--config"])
            .arg(&cfg_path)
            .arg("--run-dir")
            .arg(&run_dir)
            .args(["--envs", "2", "--eval-every", "0.02", "--eval-runs", "1", "--max-minutes", minutes])
            .output()
            .unwrap();
        assert!(out.status.success(), "actor train: {}", String::from_utf8_lossy(&out.stderr));
    };
    let lines = || -> Vec<serde_json::Value> {
        let text = std::fs::read_to_string(run_dir.join("eval.jsonl")).unwrap();
        text.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
    };
    train("0.15");
    let first = lines().len();
    assert!(first >= 1, "no periodic evaluation in 9 s at one every 1.2 s");
    train("0.3");
    let all = lines();
    assert!(all.len() > first, "the resumed run evaluated nothing");
    let score = |e: &serde_json::Value| e["selection_score"].as_f64().expect("a selection score");
    let mut best = f64::NEG_INFINITY;
    for e in &all {
        let (clean, hazards) = (e["driving_score"].as_f64().unwrap(), e["hazard_driving_score"].as_f64().unwrap());
        assert!((score(e) - 0.5 * (clean + hazards)).abs() < 1e-12, "{e}");
        // One score per hazard kind, whose mean (the same runs per kind) is the suite's.
        let kinds: Vec<f64> = e["hazard_kinds"].as_array().unwrap().iter().map(|k| k["driving_score"].as_f64().unwrap()).collect();
        assert_eq!(kinds.len(), 7, "{e}");
        assert!((kinds.iter().sum::<f64>() / 7.0 - hazards).abs() < 1e-9, "{e}");
        // Marked best exactly when it beats every earlier one, the first session's included.
        assert_eq!(e["best"].as_bool().unwrap_or(false), score(e) > best, "{e}");
        best = best.max(score(e));
    }
    let chosen: serde_json::Value = serde_json::from_slice(&std::fs::read(run_dir.join("best/best.json")).unwrap()).unwrap();
    assert_eq!(score(&chosen), best);
    let out = Command::new(env!("CARGO_BIN_EXE_actor"))
        .args(["eval", "--suite", "clean", "--runs", "1", "--json", "--checkpoint"])
        .arg(run_dir.join("best"))
        .output()
        .unwrap();
    assert!(out.status.success(), "actor eval of best/: {}", String::from_utf8_lossy(&out.stderr));
    let state: serde_json::Value = serde_json::from_slice(&std::fs::read(run_dir.join("best/state.json")).unwrap()).unwrap();
    assert_eq!(state["counters"]["env_steps"], chosen["env_steps"]);
}
