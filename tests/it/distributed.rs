//! Cross-process tests of distributed training: a learner (in this process, so that it can be
//! stopped and resumed) and actor processes over loopback gRPC; the episode summaries they send
//! reach `episodes.jsonl`. Bounded in time: every wait has a deadline and fails with the status it
//! last saw.

use crate::support;

use std::path::Path;
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use proto::v1 as pb;
use support::{Process, Signal, actor, free_port, signal, status, wait_for};

/// A run small enough to train in seconds: 16×16 gray camera, a tiny network.
fn config(run_dir: &Path, listen: &str) -> RunConfig {
    let mut cfg = RunConfig::tiny(run_dir);
    cfg.env.traffic.vehicles = 5;
    cfg.agent.min_replay = 64;
    cfg.agent.replay_capacity = 5000;
    cfg.agent.replay_ratio = 0.5;
    cfg.service.listen = listen.into();
    cfg.service.actor_timeout_secs = 2;
    cfg
}

async fn start_learner(dir: &Path, listen: &str, resume: bool) -> Running {
    let cfg_path = dir.join("run.toml");
    std::fs::write(&cfg_path, config(&dir.join("run"), listen).to_toml()).unwrap();
    start(ServeOptions { config: Some(cfg_path), resume, ..ServeOptions::default() }).await.unwrap()
}

fn spawn_actor(addr: &str, name: &str, log: &Path) -> Process {
    support::spawn_actor(addr, name, &["--batch-steps", "16"], log)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn actors_train_survive_each_other_and_a_learner_restart() {
    let dir = tempfile::tempdir().unwrap();
    let addr = free_port();
    let learner = start_learner(dir.path(), &addr, false).await;
    let mut a = spawn_actor(&addr, "a", &dir.path().join("a.log"));
    let mut b = spawn_actor(&addr, "b", &dir.path().join("b.log"));

    // Both actors' transitions are counted and the weights version advances.
    let s = wait_for(&addr, 120, "two actors feeding and new weights", |s| {
        s.weights_version > 2 && ["a", "b"].iter().all(|n| actor(s, n).is_some_and(|x| x.transitions > 0))
    })
    .await;
    assert_eq!(s.transitions_rejected, 0);

    // A malformed batch from a third party is refused and disturbs no one.
    let mut bad = proto::client::connect(&addr, None).await.unwrap();
    let reg =
        bad.register(pb::RegisterRequest { name: "bad".into(), envs: 1, protocol: 1, ..Default::default() }).await.unwrap().into_inner();
    let step = pb::Step {
        obs: Some(pb::Observation { image: vec![0; 3], speed: 0.0, d: 0.0, path: Vec::new(), vector: Vec::new() }),
        ..pb::Step::default()
    };
    let batch = pb::ExperienceBatch { actor_id: reg.actor_id, seq: 1, steps: vec![step], ..pb::ExperienceBatch::default() };
    let mut acks = bad.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
    assert_eq!(acks.message().await.unwrap_err().code(), tonic::Code::InvalidArgument);
    let before = actor(&status(&addr).await, "a").unwrap().transitions;
    wait_for(&addr, 60, "actor a still streaming after the bad batch", |s| actor(s, "a").is_some_and(|x| x.transitions > before)).await;

    // kill -9 of one actor: the learner keeps training and the status shows it gone.
    b.kill9();
    let step_then = status(&addr).await.learner_step;
    wait_for(&addr, 60, "b disconnected while training continues", |s| {
        actor(s, "b").is_some_and(|x| !x.connected) && s.learner_step > step_then
    })
    .await;

    // The learner stops (checkpoint) and comes back with --resume on the same address: the actor
    // reconnects by itself and the counters continue.
    let stopped = status(&addr).await;
    learner.stop().await.unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    let learner = start_learner(dir.path(), &addr, true).await;
    let s = status(&addr).await;
    assert_eq!(s.run_id, stopped.run_id);
    assert!(s.learner_step >= stopped.learner_step && s.transitions_stored >= stopped.transitions_stored, "{s:#?} after {stopped:#?}");
    wait_for(&addr, 90, "actor a back and streaming after the restart", |s| {
        actor(s, "a").is_some_and(|x| x.connected && x.transitions > 0) && s.transitions_stored > stopped.transitions_stored
    })
    .await;

    // SIGTERM: the actor flushes and exits 0.
    assert!(signal(a.pid(), Signal::TERM));
    let deadline = Instant::now() + Duration::from_secs(20);
    let code = loop {
        if let Some(st) = a.0.try_wait().unwrap() {
            break st;
        }
        assert!(Instant::now() < deadline, "actor did not exit after SIGTERM");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert!(code.success(), "actor exit status {code:?}; log:\n{}", std::fs::read_to_string(dir.path().join("a.log")).unwrap());
    learner.stop().await.unwrap();
}

/// An actor's episode summaries reach `episodes.jsonl` with their hazard kind and outcome.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn episodes_jsonl_names_each_episodes_hazard_and_outcome() {
    use learner::telemetry::records::{OUTCOMES, read_episodes};
    use sim_core::hazards::{HazardKind, HazardsConfig};

    let dir = tempfile::tempdir().unwrap();
    let addr = free_port();
    // Every episode has a hazard, and a short time limit ends the episodes quickly.
    let mut cfg = config(&dir.path().join("run"), &addr);
    cfg.env.hazards = HazardsConfig { rate: 1.0, kinds: vec![HazardKind::StalledCar, HazardKind::CutIn], ..HazardsConfig::default() };
    cfg.env.time_limit = 30;
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
    let learner = start(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }).await.unwrap();
    let mut a = spawn_actor(&addr, "a", &dir.path().join("a.log"));
    wait_for(&addr, 120, "four finished episodes", |s| s.episodes.as_ref().is_some_and(|e| e.episodes_total >= 4)).await;
    a.kill9();
    // Stopping flushes episodes.jsonl.
    learner.stop().await.unwrap();

    let eps = read_episodes(&dir.path().join("run/episodes.jsonl")).unwrap();
    assert!(eps.len() >= 4, "{eps:?}");
    for e in &eps {
        assert!(matches!(e.hazard.as_deref(), Some("stalled_car" | "cut_in")), "{e:?}");
        assert!(OUTCOMES.contains(&e.outcome.as_str()), "{e:?}");
        let expected = match e.outcome.as_str() {
            "arrived" => e.arrived && e.collision.is_none(),
            "collision" => !e.arrived && e.collision.is_some(),
            _ => !e.arrived && e.collision.is_none() && e.steps == 30,
        };
        assert!(expected, "the outcome contradicts the flags or the time limit: {e:?}");
    }
}
