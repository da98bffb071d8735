//! Physically impossible numbers from a raw client (not the actor, which never sends them):
//! speed 1e30 m/s, d −1e30 m, reward 3e38 are each refused with `INVALID_ARGUMENT` naming the
//! value and the bound, counted like every refusal, and a batch within the bounds still goes
//! through on the same registration. Likewise for the vector sensor's readings (wrong length,
//! NaN, beyond [−1, 1]), and an actor that writes another vector layout is refused at `Register`.

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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vector_readings_of_the_wrong_length_nan_or_beyond_one_are_refused_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = RunConfig::tiny(&dir.path().join("run"));
    cfg.env.camera = None;
    cfg.env.vector = Some(sim_core::sensor::VectorConfig::default());
    let n = cfg.vector_len();
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
    let running = start(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }).await.unwrap();
    let mut c = LearnerClient::connect(format!("http://{}", running.addr)).await.unwrap();

    // An actor of another layout, or one that predates the sensor, is refused naming both.
    for (theirs, named) in [("vector/0", "`vector/0`"), ("", "none (it predates the vector sensor)")] {
        let e = c.register(pb::RegisterRequest { vector_layout: theirs.into(), ..register_request("old") }).await.unwrap_err();
        assert_eq!(e.code(), Code::FailedPrecondition, "{}", e.message());
        let want = format!("layout `{}`, the actor writes {named}", sim_core::sensor::LAYOUT_VERSION);
        assert!(e.message().contains(&want), "{} lacks {want}", e.message());
    }
    let reg = c
        .register(pb::RegisterRequest { vector_layout: sim_core::sensor::LAYOUT_VERSION.into(), ..register_request("raw") })
        .await
        .unwrap()
        .into_inner();
    let step = |t: u32, vector: Vec<f32>| pb::Step {
        t,
        obs: Some(pb::Observation { image: Vec::new(), speed: 1.0, d: 0.5, path: Vec::new(), vector }),
        action: 1,
        reward: 0.1,
        ..Default::default()
    };
    let mut nan = vec![0.5; n];
    nan[7] = f32::NAN;
    let mut beyond = vec![-1.0; n];
    beyond[n - 1] = 1.5;
    let cases = [
        (step(1, vec![0.0; n - 1]), format!("vector has {} values; this run's [env.vector] reads {n} values", n - 1)),
        (step(1, Vec::new()), format!("vector has 0 values; this run's [env.vector] reads {n} values")),
        (step(1, nan), "vector value 7 is NaN; the vector sensor's values are finite and within [-1, 1]".to_owned()),
        (step(1, beyond), format!("vector value {} is 1.5; the vector sensor's values are finite and within [-1, 1]", n - 1)),
    ];
    for (seq, (s, expected)) in cases.into_iter().enumerate() {
        let batch =
            pb::ExperienceBatch { actor_id: reg.actor_id.clone(), seq: seq as u64 + 1, steps: vec![s], epsilon: 0.5, ..Default::default() };
        let mut acks = c.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
        let e = acks.message().await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{}", e.message());
        assert!(e.message().contains(&expected), "{} lacks {expected}", e.message());
    }
    let st = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
    assert_eq!(st.batches_rejected, 4);
    // Readings at the bounds are taken, and stored without frames.
    let fine = vec![step(0, vec![1.0; n]), step(1, vec![-1.0; n])];
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
