//! The learner service over real gRPC on 127.0.0.1:0, in one process: fake actors send good and
//! bad batches; status, health, weights, authentication, stop and resume.

use std::path::Path;
use std::time::Duration;

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use proto::v1 as pb;
use proto::v1::learner_client::LearnerClient;
use tonic::Code;
use tonic::transport::Channel;

async fn start_tiny(dir: &Path, resume: bool, token: Option<&Path>) -> Running {
    let cfg_path = dir.join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&dir.join("run")).to_toml()).unwrap();
    start(ServeOptions { config: Some(cfg_path), resume, auth_token_file: token.map(Path::to_path_buf), ..ServeOptions::default() })
        .await
        .unwrap()
}

async fn client(r: &Running) -> LearnerClient<Channel> {
    LearnerClient::connect(format!("http://{}", r.addr)).await.unwrap()
}

async fn register(c: &mut LearnerClient<Channel>, name: &str) -> pb::RegisterResponse {
    c.register(pb::RegisterRequest { name: name.into(), envs: 2, protocol: 1, ..Default::default() }).await.unwrap().into_inner()
}

/// `n` steps of one episode of env 0 starting at `t0` (t = 0 is the reset observation).
fn steps(episode: u64, t0: u32, n: u32, image_bytes: usize) -> Vec<pb::Step> {
    (t0..t0 + n)
        .map(|t| pb::Step {
            env: 0,
            episode,
            t,
            obs: Some(pb::Observation {
                image: vec![(t * 7 % 256) as u8; image_bytes],
                speed: t as f32 * 0.5,
                d: 1.0,
                path: Vec::new(),
                vector: Vec::new(),
            }),
            action: t % 6,
            reward: 0.1,
            terminated: false,
            truncated: false,
        })
        .collect()
}

fn batch(actor: &str, seq: u64, steps: Vec<pb::Step>) -> pb::ExperienceBatch {
    pb::ExperienceBatch {
        actor_id: actor.into(),
        seq,
        steps,
        episodes: vec![],
        weights_version: 1,
        epsilon: 0.5,
        dropped_steps: 0,
        demonstration: false,
    }
}

/// Sends batches on one stream; returns each batch's outcome (ack or error code and message).
async fn send(c: &mut LearnerClient<Channel>, batches: Vec<pb::ExperienceBatch>) -> Vec<Result<pb::BatchAck, (Code, String)>> {
    let n = batches.len();
    let mut acks = c.stream_experience(tokio_stream::iter(batches)).await.unwrap().into_inner();
    let mut out = Vec::new();
    while out.len() < n {
        match acks.message().await {
            Ok(Some(a)) => out.push(Ok(a)),
            Ok(None) => break,
            Err(s) => {
                out.push(Err((s.code(), s.message().to_owned())));
                break;
            }
        }
    }
    out
}

async fn status(c: &mut LearnerClient<Channel>) -> pb::StatusResponse {
    c.status(pb::StatusRequest {}).await.unwrap().into_inner()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn good_batches_are_stored_bad_ones_refused_and_training_publishes_weights() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, None).await;
    let mut c = client(&running).await;
    let good = register(&mut c, "good").await;
    let bad = register(&mut c, "bad").await;
    assert_eq!((good.actor_index, bad.actor_index), (0, 1));
    assert!(good.env_config_toml.contains("variant = \"hybrid\""), "{}", good.env_config_toml);
    let img = 16 * 16;

    // Good: 41 steps (t = 0..=40) in two batches → 40 transitions.
    let acks = send(&mut c, vec![batch(&good.actor_id, 1, steps(0, 0, 21, img)), batch(&good.actor_id, 2, steps(0, 21, 20, img))]).await;
    assert_eq!(acks.iter().map(|a| a.as_ref().unwrap().stored).collect::<Vec<_>>(), vec![20, 20]);

    // Bad batches, each on its own stream, each refused whole with a reason.
    let mut wrong_size = steps(5, 0, 3, img);
    wrong_size[2].obs.as_mut().unwrap().image.pop();
    let mut wrong_action = steps(5, 0, 3, img);
    wrong_action[1].action = 6;
    let mut nan = steps(5, 0, 3, img);
    nan[2].reward = f32::NAN;
    let mut short_path = steps(5, 0, 3, img);
    short_path[1].obs.as_mut().unwrap().path = vec![0.5, 0.1];
    let mut nan_path = steps(5, 0, 3, img);
    nan_path[1].obs.as_mut().unwrap().path = vec![0.5, f32::NAN, 0.0];
    let cases: Vec<(Vec<pb::Step>, Code, &str)> = vec![
        (wrong_size, Code::InvalidArgument, "image has 255 bytes; this run's camera is 16x16x1 = 256 bytes"),
        (wrong_action, Code::InvalidArgument, "action 6 is out of range 0..6"),
        (nan, Code::InvalidArgument, "reward is NaN"),
        (short_path, Code::InvalidArgument, "2 path features; expected 3 or none"),
        (nan_path, Code::InvalidArgument, "path is NaN"),
        (steps(5, 0, 5000, img), Code::ResourceExhausted, "5000 steps; at most 4096"),
    ];
    for (k, (s, code, text)) in cases.into_iter().enumerate() {
        let out = send(&mut c, vec![batch(&bad.actor_id, k as u64, s)]).await;
        let (got, msg) = out[0].as_ref().expect_err("refused");
        assert_eq!(*got, code, "{msg}");
        assert!(msg.contains(text), "{msg}");
    }
    // Unknown actor.
    let out = send(&mut c, vec![batch("nobody", 1, steps(0, 0, 2, img))]).await;
    assert_eq!(out[0].as_ref().unwrap_err().0, Code::FailedPrecondition);

    // The good actor is unaffected, and its transitions fill the replay to the training minimum.
    let acks = send(&mut c, vec![batch(&good.actor_id, 3, steps(0, 41, 30, img))]).await;
    assert_eq!(acks[0].as_ref().unwrap().stored, 30);

    // Training starts (70 stored ≥ 32) and publishes weights every 2 updates.
    let mut st = status(&mut c).await;
    for _ in 0..200 {
        if st.weights_version > 1 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
        st = status(&mut c).await;
    }
    assert!(st.weights_version > 1, "weights published: {st:?}");
    assert!(st.learner_step >= 2);
    assert_eq!((st.transitions_stored, st.replay_size), (70, 70));
    assert_eq!(st.batches_rejected, 6, "six invalid batches (the unknown actor is refused before validation)");
    assert_eq!(st.transitions_rejected, 2 + 2 + 2 + 2 + 2 + 4999);
    let by_name = |n: &str| st.actors.iter().find(|a| a.name == n).unwrap().clone();
    assert_eq!((by_name("good").transitions, by_name("good").rejected_batches), (70, 0));
    assert_eq!((by_name("bad").transitions, by_name("bad").rejected_batches), (0, 6));
    // Its streams are all closed: not connected, however recently it sent (reliability.rs tests
    // an open stream).
    assert!(!by_name("good").connected && by_name("good").open_streams == 0);
    assert_eq!(st.variant, "hybrid");

    // Weights: the newest when behind, nothing when up to date.
    let w = c.get_weights(pb::GetWeightsRequest { actor_id: good.actor_id.clone(), have_version: 0 }).await.unwrap().into_inner();
    assert!(w.version > 1 && w.safetensors.len() > 1000);
    let same =
        c.get_weights(pb::GetWeightsRequest { actor_id: good.actor_id.clone(), have_version: w.version }).await.unwrap().into_inner();
    // Training goes on meanwhile: either nothing newer (no bytes) or a newer version with bytes.
    assert_eq!(same.safetensors.is_empty(), same.version == w.version, "version {} after {}", same.version, w.version);

    // Health: SERVING.
    let channel = tonic::transport::Endpoint::from_shared(format!("http://{}", running.addr)).unwrap().connect().await.unwrap();
    let mut health = tonic_health::pb::health_client::HealthClient::new(channel);
    let h = health.check(tonic_health::pb::HealthCheckRequest { service: "hybriddrive.v1.Learner".into() }).await.unwrap().into_inner();
    assert_eq!(h.status(), tonic_health::pb::health_check_response::ServingStatus::Serving);

    // Stop: a checkpoint and the effective config are in the run directory.
    let path = running.stop().await.unwrap();
    assert!(path.join("manifest.json").exists());
    assert!(dir.path().join("run/config.toml").exists());
    let episodes = std::fs::read_to_string(dir.path().join("run/train.jsonl")).unwrap();
    assert!(episodes.lines().count() >= 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resume_continues_the_counters_and_weights() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, None).await;
    let mut c = client(&running).await;
    let a = register(&mut c, "a").await;
    send(&mut c, vec![batch(&a.actor_id, 1, steps(0, 0, 60, 256))]).await;
    let mut st = status(&mut c).await;
    for _ in 0..200 {
        if st.learner_step >= 4 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
        st = status(&mut c).await;
    }
    let run_id = st.run_id.clone();
    running.stop().await.unwrap();

    // Starting again without --resume refuses to overwrite the run.
    let cfg_path = dir.path().join("run.toml");
    let err = start(ServeOptions { config: Some(cfg_path.clone()), ..ServeOptions::default() }).await.unwrap_err();
    assert!(err.to_string().contains("already holds a checkpoint: pass --resume"), "{err}");

    let again = start_tiny(dir.path(), true, None).await;
    let mut c = client(&again).await;
    let st2 = status(&mut c).await;
    assert_eq!(st2.run_id, run_id);
    // The final checkpoint holds every update done before the stop, at least those seen above.
    assert!(st2.learner_step >= st.learner_step && st2.learner_step >= 4, "{} after {}", st2.learner_step, st.learner_step);
    assert_eq!(st2.transitions_stored, 59);
    assert!(st2.weights_version >= st.weights_version);
    again.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_token_is_required_when_configured() {
    let dir = tempfile::tempdir().unwrap();
    let token = dir.path().join("token");
    std::fs::write(&token, "s3cret\n").unwrap();
    let cfg_path = dir.path().join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&dir.path().join("run")).to_toml()).unwrap();
    let running = start(ServeOptions {
        config: Some(cfg_path),
        auth_token_file: Some(token.clone()),
        metrics_listen: Some("127.0.0.1:0".into()),
        ..ServeOptions::default()
    })
    .await
    .unwrap();
    let mut c = client(&running).await;
    let err = c.status(pb::StatusRequest {}).await.unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated);
    let mut authed = proto::client::connect(&running.addr.to_string(), Some("s3cret".into())).await.unwrap();
    assert!(authed.status(pb::StatusRequest {}).await.is_ok());
    let mut wrong = proto::client::connect(&running.addr.to_string(), Some("nope".into())).await.unwrap();
    assert_eq!(wrong.status(pb::StatusRequest {}).await.unwrap_err().code(), Code::Unauthenticated);

    // The Prometheus endpoint answers plain HTTP with the text format.
    let addr = std::fs::read_to_string(dir.path().join("run/metrics.addr")).unwrap();
    let mut sock = tokio::net::TcpStream::connect(addr.trim()).await.unwrap();
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    sock.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    let mut body = String::new();
    sock.read_to_string(&mut body).await.unwrap();
    assert!(body.starts_with("HTTP/1.1 200 OK"), "{body}");
    assert!(body.contains("# TYPE learner_updates_total counter\nlearner_updates_total 0\n"), "{body}");
    assert!(body.contains("learner_weights_version 1\n"), "{body}");
    running.stop().await.unwrap();
}

/// A burst of batches on one stream against a learner whose updates are slower than the batches
/// arrive (8 samples trained per transition inserted): with `service.update_lag_limit` the
/// stream is held until the learner has caught up to within the limit and one batch; without
/// it (0), the burst is stored at once and the learner is left hundreds of updates behind.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn streams_wait_for_a_learner_behind_the_replay_ratio() {
    async fn burst(limit: u64) -> (u64, f64) {
        let dir = tempfile::tempdir().unwrap();
        let mut cfg = RunConfig::tiny(&dir.path().join("run"));
        (cfg.agent.replay_ratio, cfg.agent.batch_size, cfg.agent.replay_capacity) = (8.0, 32, 5000);
        cfg.service.update_lag_limit = limit;
        let cfg_path = dir.path().join("run.toml");
        std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
        let running = start(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }).await.unwrap();
        let mut c = client(&running).await;
        let a = register(&mut c, "a").await;
        // One episode per batch (t = 0 is its reset): 99 transitions each.
        let batches = (0..8).map(|k| batch(&a.actor_id, k + 1, steps(k, 0, 100, 256))).collect();
        let acks = send(&mut c, batches).await;
        assert!(acks.iter().all(Result::is_ok), "{acks:?}");
        let st = status(&mut c).await;
        assert_eq!(st.transitions_stored, 8 * 99);
        // Owed now: every transition stored counts (the replay reached its minimum from empty).
        let owed = (st.transitions_stored * 8 / 32).saturating_sub(st.learner_step);
        println!("update_lag_limit {limit}: {owed} updates owed after the burst, streams held {:.2} s", st.held_secs);
        running.stop().await.unwrap();
        (owed, st.held_secs)
    }
    let (owed, held) = burst(4).await;
    // At most the limit, plus the 24.75 updates of the last batch stored, plus one of rounding.
    assert!(owed <= 4 + 25 + 1, "{owed} updates owed after the burst, with update_lag_limit = 4");
    assert!(held > 0.0, "the stream was held: held_secs {held}");
    let (owed, held) = burst(0).await;
    assert!(owed > 100, "without the hold the burst leaves the learner behind: {owed} updates owed");
    assert!(held == 0.0, "nothing is held with update_lag_limit = 0: held_secs {held}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn episode_summaries_reach_episodes_jsonl_with_their_hazard_and_outcome() {
    use learner::telemetry::records::read_episodes;
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, None).await;
    let mut c = client(&running).await;
    let a = register(&mut c, "a").await;
    let summary = |episode: u64, hazard: &str, outcome: &str, arrived: bool, collision: &str| pb::EpisodeSummary {
        env: 0,
        episode,
        episode_return: 2.5,
        steps: 10,
        arrived,
        collision: collision.into(),
        scenario: "random".into(),
        hazard: hazard.into(),
        outcome: outcome.into(),
    };
    let with =
        |seq: u64, episodes: Vec<pb::EpisodeSummary>| pb::ExperienceBatch { episodes, ..batch(&a.actor_id, seq, steps(seq, 0, 3, 256)) };
    let acks = send(
        &mut c,
        vec![with(
            1,
            vec![
                summary(0, "pedestrian_crossing", "collision", false, "walker"),
                summary(1, "", "timeout", false, ""),
                // From an actor that predates hazard and outcome.
                summary(2, "", "", true, ""),
            ],
        )],
    )
    .await;
    assert!(acks[0].is_ok(), "{acks:?}");
    // An unknown kind is refused with the batch, as the other malformed fields are.
    let out = send(&mut c, vec![with(2, vec![summary(3, "meteor", "collision", false, "vehicle")])]).await;
    let (code, msg) = out[0].as_ref().expect_err("refused");
    assert_eq!(*code, Code::InvalidArgument, "{msg}");
    assert!(msg.contains("episode summary 0: unknown hazard `meteor`"), "{msg}");
    running.stop().await.unwrap();

    let eps = read_episodes(&dir.path().join("run/episodes.jsonl")).unwrap();
    let got: Vec<(Option<&str>, &str, bool, Option<&str>)> =
        eps.iter().map(|e| (e.hazard.as_deref(), e.outcome.as_str(), e.arrived, e.collision.as_deref())).collect();
    assert_eq!(
        got,
        [(Some("pedestrian_crossing"), "collision", false, Some("walker")), (None, "timeout", false, None), (None, "arrived", true, None)]
    );
    // The line itself names both fields (no hazard: null).
    let text = std::fs::read_to_string(dir.path().join("run/episodes.jsonl")).unwrap();
    assert!(text.lines().next().unwrap().contains(r#""hazard":"pedestrian_crossing","outcome":"collision""#), "{text}");
    assert!(text.lines().nth(1).unwrap().contains(r#""hazard":null,"outcome":"timeout""#), "{text}");
}
