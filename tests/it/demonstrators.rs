//! A demonstrator process (`actor --demonstrate`) beside a learning actor, against a learner in
//! this process: it registers as a demonstrator, its steps arrive as demonstrations and are kept
//! apart from the agent's, and it does not outrun the learning actor for long.

use crate::support;

use std::path::Path;

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use support::{actor, status, wait_for};

async fn start_learner(dir: &Path) -> Running {
    let mut cfg = RunConfig::tiny(&dir.join("run"));
    // Hazards the avoiding planner drives round, on the hazard suite's episodes.
    cfg.env.hazards.rate = 0.5;
    (cfg.agent.min_replay, cfg.agent.replay_capacity) = (2000, 5000);
    let path = dir.join("run.toml");
    std::fs::write(&path, cfg.to_toml()).unwrap();
    start(ServeOptions { config: Some(path), ..ServeOptions::default() }).await.unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_demonstrator_streams_demonstrations_beside_a_learning_actor() {
    let dir = tempfile::tempdir().unwrap();
    let learner = start_learner(dir.path()).await;
    let addr = learner.addr.to_string();
    let mut teacher = support::spawn_actor(&addr, "teacher", &["--demonstrate", "model-based-avoid"], &dir.path().join("t.log"));
    let mut agent = support::spawn_actor(&addr, "agent", &[], &dir.path().join("a.log"));
    let s = wait_for(&addr, 120, "demonstrations and the agent's steps stored", |s| {
        s.demo_transitions_stored >= 1000 && s.transitions_stored >= 1000
    })
    .await;
    let (t, a) = (actor(&s, "teacher").unwrap(), actor(&s, "agent").unwrap());
    assert_eq!((t.demonstrator.as_str(), a.demonstrator.as_str()), ("model-based-avoid", ""));
    assert_eq!((t.rejected_batches, a.rejected_batches, s.batches_rejected), (0, 0, 0), "{s:#?}");
    // The teacher's transitions are the demonstration partition's, the agent's the run's env
    // steps; neither sees the other's.
    assert_eq!(s.demo_replay_size, s.demo_transitions_stored.min(s.demo_replay_capacity));
    assert!(t.transitions <= s.demo_transitions_stored && a.transitions <= s.transitions_stored, "{s:#?}");
    assert_eq!(t.epsilon, 0.0, "a demonstrator does not explore");
    // Its pace: it pauses once the demonstrations catch up with the agent's steps (polled once
    // a second, so it may be ahead by what it drives meanwhile, never by ten times).
    let later = status(&addr).await;
    assert!(later.demo_transitions_received < 10 * later.env_steps.max(1000), "{later:#?}");
    teacher.kill9();
    agent.kill9();
    learner.stop().await.unwrap();
}
