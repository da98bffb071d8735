//! Demonstrations (`actor --demonstrate`) seen from outside, against a learner on 127.0.0.1:0 in
//! this process: who may send them, that Status counts them apart from the agent's experience and
//! that training draws its share of them, and that they survive a crash image (the disk as a
//! SIGKILL leaves it) resumed with `--resume`, back in their own partition.

use std::path::Path;
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use proto::v1 as pb;
use proto::v1::learner_client::LearnerClient;
use tonic::Code;
use tonic::transport::Channel;

async fn start_tiny(dir: &Path, edit: impl FnOnce(&mut RunConfig)) -> Running {
    let cfg_path = dir.join("run.toml");
    let mut cfg = RunConfig::tiny(&dir.join("run"));
    edit(&mut cfg);
    std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
    start(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }).await.unwrap()
}

async fn client(addr: &str) -> LearnerClient<Channel> {
    LearnerClient::connect(format!("http://{addr}")).await.unwrap()
}

async fn register(c: &mut LearnerClient<Channel>, name: &str, demonstrator: &str) -> Result<pb::RegisterResponse, tonic::Status> {
    let req = pb::RegisterRequest { name: name.into(), envs: 1, protocol: 1, demonstrator: demonstrator.into(), ..Default::default() };
    Ok(c.register(req).await?.into_inner())
}

async fn status(c: &mut LearnerClient<Channel>) -> pb::StatusResponse {
    c.status(pb::StatusRequest {}).await.unwrap().into_inner()
}

/// `n` steps of env 0, episode 0, from `t0`, marked as demonstrations or not; the frames of
/// demonstrations are odd bytes, the agent's even.
fn batch(actor: &str, seq: u64, t0: u32, n: u32, demonstration: bool) -> pb::ExperienceBatch {
    let steps = (t0..t0 + n)
        .map(|t| pb::Step {
            t,
            obs: Some(pb::Observation {
                image: vec![(2 * (t % 100) + u32::from(demonstration)) as u8; 256],
                speed: 1.0,
                d: 0.5,
                ..Default::default()
            }),
            action: t % 6,
            reward: 0.1,
            ..Default::default()
        })
        .collect();
    pb::ExperienceBatch { actor_id: actor.into(), seq, steps, demonstration, weights_version: 1, ..Default::default() }
}

async fn send(c: &mut LearnerClient<Channel>, batches: Vec<pb::ExperienceBatch>) -> Result<Vec<pb::BatchAck>, tonic::Status> {
    let n = batches.len();
    let mut acks = c.stream_experience(tokio_stream::iter(batches)).await?.into_inner();
    let mut out = Vec::new();
    while out.len() < n {
        match acks.message().await? {
            Some(a) => out.push(a),
            None => break,
        }
    }
    Ok(out)
}

/// Only a demonstrator's registration may send demonstrations, and a demonstrator sends nothing
/// else: either mismatch ends the stream with INVALID_ARGUMENT naming it, nothing of the batch is
/// stored, and the refusal is counted. A run that keeps no demonstrations refuses demonstrators
/// at Register.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demonstrations_come_from_demonstrators_alone() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), |_| {}).await;
    let mut c = client(&running.addr.to_string()).await;
    // The demonstrator first: the learning actor is still index 0 (Ape-X's ε counts learning
    // actors alone).
    let demo = register(&mut c, "teacher", "model-based-avoid").await.unwrap();
    let agent = register(&mut c, "agent", "").await.unwrap();
    assert_eq!((agent.actor_index, demo.actor_index), (0, learner::service::rpc::DEMONSTRATOR_INDEX));

    let refused = send(&mut c, vec![batch(&agent.actor_id, 1, 0, 10, true)]).await.unwrap_err();
    assert_eq!(refused.code(), Code::InvalidArgument);
    assert!(
        refused.message().contains("marked as demonstrations, but actor `agent` registered as a learning actor"),
        "{}",
        refused.message()
    );
    let refused = send(&mut c, vec![batch(&demo.actor_id, 1, 0, 10, false)]).await.unwrap_err();
    assert_eq!(refused.code(), Code::InvalidArgument);
    assert!(refused.message().contains("registered as a demonstrator (`model-based-avoid`)"), "{}", refused.message());
    let st = status(&mut c).await;
    assert_eq!((st.batches_rejected, st.replay_size, st.demo_replay_size, st.demo_transitions_received), (2, 0, 0, 0));

    // The right pairings are stored, each in its partition, counted apart.
    send(&mut c, vec![batch(&agent.actor_id, 2, 0, 10, false)]).await.unwrap();
    send(&mut c, vec![batch(&demo.actor_id, 2, 0, 21, true)]).await.unwrap();
    let st = status(&mut c).await;
    assert_eq!((st.replay_size, st.transitions_stored, st.env_steps), (9, 9, 9));
    assert_eq!((st.demo_replay_size, st.demo_transitions_stored, st.demo_transitions_received), (20, 20, 20));
    let roles: Vec<(&str, &str)> = st.actors.iter().map(|a| (a.name.as_str(), a.demonstrator.as_str())).collect();
    assert_eq!(roles, [("teacher", "model-based-avoid"), ("agent", "")]);
    running.stop().await.unwrap();

    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), |cfg| cfg.agent.demo_capacity = 0).await;
    let mut c = client(&running.addr.to_string()).await;
    let e = register(&mut c, "teacher", "model-based").await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    assert!(e.message().contains("demo_capacity = 0"), "{}", e.message());
    running.stop().await.unwrap();
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &target);
        } else if let Err(err) = std::fs::copy(e.path(), &target) {
            assert_eq!(err.kind(), std::io::ErrorKind::NotFound, "{err}");
        }
    }
}

/// Training draws its share of demonstrations (Status's share of the last batches, the margin
/// loss), and a crash image taken while it runs resumes with every acknowledged demonstration
/// back in the demonstration partition and the agent's experience in its own. A small agent
/// partition that the agent's experience overfills evicts none of the demonstrations.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demonstrations_are_trained_on_and_survive_a_crash_image_and_resume() {
    let dir = tempfile::tempdir().unwrap();
    let edit = |cfg: &mut RunConfig| {
        (cfg.agent.replay_capacity, cfg.agent.demo_capacity, cfg.agent.demo_share) = (100, 500, 0.5);
        // A segment per few batches, so that deleting segments is exercised.
        cfg.service.replay_log_segment_bytes = 64 << 10;
    };
    let running = start_tiny(dir.path(), edit).await;
    let addr = running.addr.to_string();
    let mut c = client(&addr).await;
    let agent = register(&mut c, "agent", "").await.unwrap();
    let demo = register(&mut c, "teacher", "model-based-avoid").await.unwrap();
    // 300 demonstration steps first, then 1000 of the agent's (ten times its partition).
    let demo_acks = send(&mut c, (0..3).map(|k| batch(&demo.actor_id, k + 1, k as u32 * 100, 100, true)).collect()).await.unwrap();
    assert_eq!(demo_acks.iter().map(|a| a.stored).sum::<u32>(), 299);
    send(&mut c, (0..10).map(|k| batch(&agent.actor_id, k + 1, k as u32 * 100, 100, false)).collect()).await.unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    let before = loop {
        let st = status(&mut c).await;
        if st.learner_step >= 50 && st.weights_version >= 4 {
            break st;
        }
        assert!(Instant::now() < deadline, "no training: {st:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!((before.replay_size, before.demo_replay_size, before.demo_replay_capacity), (100, 299, 500));
    assert!(before.transitions_evicted > 0, "the agent's partition overflowed");
    assert!((0.3..0.7).contains(&before.demo_batch_share), "share of demonstrations in the last batches: {}", before.demo_batch_share);
    assert!(before.margin_loss.is_finite() && before.margin_loss >= 0.0, "{}", before.margin_loss);
    assert_eq!(before.demo_share, 0.5);
    let image = tempfile::tempdir().unwrap();
    copy_tree(&dir.path().join("run"), &image.path().join("run"));
    std::fs::copy(dir.path().join("run.toml"), image.path().join("run.toml")).unwrap();
    running.stop().await.unwrap();

    let again = start(ServeOptions {
        config: Some(image.path().join("run.toml")),
        run_dir: Some(image.path().join("run")),
        resume: true,
        ..ServeOptions::default()
    })
    .await
    .unwrap();
    let mut c = client(&again.addr.to_string()).await;
    let st = status(&mut c).await;
    assert_eq!(st.run_id, before.run_id);
    assert_eq!((st.replay_size, st.demo_replay_size), (100, 299), "both partitions rebuilt from the replay log");
    assert_eq!((st.demo_transitions_received, st.demo_transitions_stored, st.transitions_stored), (299, 299, 999));
    again.stop().await.unwrap();
}

/// Pre-training: `demo_pretrain_updates` updates on demonstrations alone once there are enough of
/// them (`min_replay`), none before; they are not the replay ratio's, so the agent's experience
/// that follows gets exactly the updates the ratio gives it (99 transitions at ratio 1, batch 8:
/// 12), on top of the 20.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pretraining_runs_on_demonstrations_before_the_agents_experience() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), |cfg| cfg.agent.demo_pretrain_updates = 20).await;
    let mut c = client(&running.addr.to_string()).await;
    assert_eq!(status(&mut c).await.demo_pretrain_updates_left, 20);
    let demo = register(&mut c, "teacher", "model-based").await.unwrap();
    // 20 demonstrations are fewer than min_replay (32): nothing yet.
    send(&mut c, vec![batch(&demo.actor_id, 1, 0, 21, true)]).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(status(&mut c).await.learner_step, 0);
    send(&mut c, vec![batch(&demo.actor_id, 2, 21, 30, true)]).await.unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let st = status(&mut c).await;
        if st.demo_pretrain_updates_left == 0 {
            assert_eq!((st.learner_step, st.demo_batch_share), (20, 1.0), "demonstrations alone");
            break;
        }
        assert!(Instant::now() < deadline, "no pre-training: {st:?}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let agent = register(&mut c, "agent", "").await.unwrap();
    send(&mut c, vec![batch(&agent.actor_id, 1, 0, 100, false)]).await.unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while status(&mut c).await.learner_step < 32 {
        assert!(Instant::now() < deadline, "the agent's updates did not come");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(status(&mut c).await.learner_step, 32, "20 pre-training updates and the ratio's 12");
    running.stop().await.unwrap();
}
