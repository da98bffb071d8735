//! Physically impossible numbers from a raw client (not the actor, which never sends them):
//! speed 1e30 m/s, d −1e30 m, reward 3e38 are each refused with `INVALID_ARGUMENT` naming the
//! value and the bound, counted like every refusal, and a batch within the bounds still goes
//! through on the same registration.

use agent::config::RunConfig;
use learner::serve::{ServeOptions, start};
use proto::v1 as pb;
use proto::v1::learner_client::LearnerClient;
use tonic::Code;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn impossible_speed_distance_and_reward_are_refused_with_the_bound() {
    let dir = tempfile::tempdir().unwrap();
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&dir.path().join("run")).to_toml()).unwrap();
    let running = start(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }).await.unwrap();
    let mut c = LearnerClient::connect(format!("http://{}", running.addr)).await.unwrap();
    let reg = c.register(register_request("raw")).await.unwrap().into_inner();
    let frame = running.shared.frame_bytes;
    let step = |t: u32, speed: f32, d: f32, reward: f32| pb::Step {
        t,
        obs: Some(pb::Observation { image: vec![7; frame], speed, d, path: Vec::new(), vector: Vec::new() }),
        action: 1,
        reward,
        ..Default::default()
    };
    let cases = [
        (step(1, 1e30, 0.5, 0.1), "speed 1000000000000000000000000000000 m/s is beyond what the vehicle can reach (|speed| <= 61 m/s"),
        (step(1, 1.0, -1e30, 0.1), "d -1000000000000000000000000000000 m is beyond how far the vehicle can get from its route (|d| <= "),
        (step(1, 1.0, 0.5, 3e38), "reward 300000000000000000000000000000000000000 is beyond what this run's reward"),
    ];
    for (seq, (s, expected)) in cases.into_iter().enumerate() {
        let batch =
            pb::ExperienceBatch { actor_id: reg.actor_id.clone(), seq: seq as u64 + 1, steps: vec![s], epsilon: 0.5, ..Default::default() };
        let mut acks = c.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
        let e = acks.message().await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{}", e.message());
        assert!(e.message().contains(expected), "{}", e.message());
    }
    let st = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
    assert_eq!(st.batches_rejected, 3);
    // Real values at the limits are taken.
    let fine = vec![step(0, 0.0, 0.0, 0.0), step(1, 30.0, 100.0, 100.0)];
    let batch = pb::ExperienceBatch { actor_id: reg.actor_id.clone(), seq: 10, steps: fine, epsilon: 0.5, ..Default::default() };
    let mut acks = c.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
    assert_eq!(acks.message().await.unwrap().unwrap().seq, 10);
    running.stop().await.unwrap();
}

/// A registration of one environment. `..Default::default()` keeps this compiling as
/// `RegisterRequest` gains fields (today it has no others).
#[allow(clippy::needless_update)]
fn register_request(name: &str) -> pb::RegisterRequest {
    pb::RegisterRequest { name: name.into(), envs: 1, protocol: proto::v1::PROTOCOL, ..Default::default() }
}
