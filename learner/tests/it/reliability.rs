//! Failures seen from outside, as a third-party client or a crash would cause them, against a
//! learner on 127.0.0.1:0 in this process: oversized and garbage messages, out-of-place batches,
//! re-registration, a connection that drops, a checkpoint that cannot be written, and a crash
//! image of the run directory (the disk as a SIGKILL leaves it) resumed with `--resume`.

use std::path::Path;
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use proto::v1 as pb;
use proto::v1::learner_client::LearnerClient;
use tonic::Code;
use tonic::transport::Channel;

/// The tiny run, with the smallest message limit (1 MiB) and `edit` applied.
async fn start_tiny(dir: &Path, resume: bool, edit: impl FnOnce(&mut RunConfig)) -> Running {
    let cfg_path = dir.join("run.toml");
    let mut cfg = RunConfig::tiny(&dir.join("run"));
    cfg.service.max_message_bytes = 1 << 20;
    edit(&mut cfg);
    std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
    start(ServeOptions { config: Some(cfg_path), resume, ..ServeOptions::default() }).await.unwrap()
}

async fn client(addr: &str) -> LearnerClient<Channel> {
    LearnerClient::connect(format!("http://{addr}")).await.unwrap()
}

async fn register(c: &mut LearnerClient<Channel>, name: &str, envs: u32) -> pb::RegisterResponse {
    c.register(pb::RegisterRequest { name: name.into(), envs, protocol: 1, ..Default::default() }).await.unwrap().into_inner()
}

async fn status(c: &mut LearnerClient<Channel>) -> pb::StatusResponse {
    c.status(pb::StatusRequest {}).await.unwrap().into_inner()
}

fn step(env: u32, episode: u64, t: u32) -> pb::Step {
    pb::Step {
        env,
        episode,
        t,
        obs: Some(pb::Observation { image: vec![(t % 251) as u8; 256], speed: 1.0, d: 0.5, path: Vec::new(), vector: Vec::new() }),
        action: t % 6,
        reward: 0.1,
        terminated: false,
        truncated: false,
    }
}

/// `n` steps of env 0, episode 0, from `t0`.
fn batch(actor: &str, seq: u64, t0: u32, n: u32) -> pb::ExperienceBatch {
    let steps = (t0..t0 + n).map(|t| step(0, 0, t)).collect();
    pb::ExperienceBatch { actor_id: actor.into(), seq, steps, epsilon: 0.5, weights_version: 1, ..pb::ExperienceBatch::default() }
}

/// Sends batches on one stream and returns the acknowledgements, or the status that ended it.
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

/// Streams raw messages to `StreamExperience` (declaring `actor` in the metadata, as actors do)
/// and returns the status the stream ended with (`Ok` with the replies if it ended with OK).
async fn raw_stream(addr: &str, actor: Option<&str>, messages: Vec<Vec<u8>>) -> Result<Vec<Vec<u8>>, tonic::Status> {
    let channel = tonic::transport::Endpoint::from_shared(format!("http://{addr}")).unwrap().connect().await.unwrap();
    proto::raw::stream_experience(channel, actor, messages).await
}

/// Issue row: "a 64 MiB message, or garbage bytes, on StreamExperience: the stream ends with status
/// OK, no acknowledgement, nothing counted".
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversized_and_garbage_streams_end_with_a_status_naming_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, |_| {}).await;
    let addr = running.addr.to_string();
    let mut c = client(&addr).await;
    let raw = register(&mut c, "raw", 1).await;

    // 2 MiB where 1 MiB is the limit.
    let err = raw_stream(&addr, Some(&raw.actor_id), vec![vec![0u8; 2 << 20]]).await.unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    assert!(err.message().contains("message too large") && err.message().contains("max_message_bytes = 1048576"), "{}", err.message());

    // Bytes that are not an ExperienceBatch (0xff: field 31 of wire type 7, which does not
    // exist), from the registered actor and from a client that never registered.
    for actor in [Some(raw.actor_id.as_str()), None] {
        let err = raw_stream(&addr, actor, vec![vec![0xff; 64]]).await.unwrap_err();
        assert_eq!(err.code(), Code::InvalidArgument, "{err:?}");
        assert!(err.message().starts_with("undecodable message: failed to decode Protobuf message"), "{}", err.message());
    }

    // Counted, by kind and for the actor; everyone else is served as before.
    let st = status(&mut c).await;
    assert_eq!((st.batches_rejected, st.streams_refused_too_large, st.streams_refused_undecodable), (3, 1, 2));
    assert_eq!(st.actors.iter().find(|a| a.name == "raw").unwrap().rejected_batches, 2);
    let good = register(&mut c, "good", 1).await;
    let acks = send(&mut c, vec![batch(&good.actor_id, 1, 0, 5)]).await.unwrap();
    assert_eq!(acks[0].stored, 4);
    running.stop().await.unwrap();
}

/// Issue row: "50 Register calls under one name: 51 actor records".
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_record_per_actor_name_however_often_it_registers() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, |_| {}).await;
    let mut c = client(&running.addr.to_string()).await;
    let other = register(&mut c, "other", 1).await;
    let mut ids = Vec::new();
    for _ in 0..50 {
        ids.push(register(&mut c, "same", 2).await);
    }
    assert!(ids.iter().all(|r| r.actor_index == 1), "the name keeps its index (and exploration rate)");
    let st = status(&mut c).await;
    assert_eq!(st.actors.len(), 2, "{:#?}", st.actors);
    let same = st.actors.iter().find(|a| a.name == "same").unwrap();
    assert_eq!((same.registrations, same.actor_id.as_str()), (50, ids[49].actor_id.as_str()));
    // Only the newest registration's id is accepted; an earlier one is told to register.
    let old = send(&mut c, vec![batch(&ids[0].actor_id, 1, 0, 3)]).await.unwrap_err();
    assert_eq!(old.code(), Code::FailedPrecondition, "{old:?}");
    assert_eq!(send(&mut c, vec![batch(&ids[49].actor_id, 1, 0, 3)]).await.unwrap()[0].stored, 2);
    assert_eq!(send(&mut c, vec![batch(&other.actor_id, 1, 0, 3)]).await.unwrap()[0].stored, 2);
    running.stop().await.unwrap();
}

/// Issue row: "kill -9 of an actor: Status lists it connected for 30 s". A dropped connection is
/// what the learner sees of a killed actor; the timeout here is 60 s, so only the closed stream
/// can make it show disconnected within the few seconds the test waits.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connected_means_an_open_stream() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, |cfg| cfg.service.actor_timeout_secs = 60).await;
    let addr = running.addr.to_string();
    let mut observer = client(&addr).await;
    let mut c = client(&addr).await;
    let reg = register(&mut c, "a", 1).await;
    let actor = |st: &pb::StatusResponse| st.actors.iter().find(|a| a.name == "a").unwrap().clone();
    assert!(!actor(&status(&mut observer).await).connected, "registered, but no stream yet");

    // An open stream (kept open: the sender lives), with a batch acknowledged.
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let mut req = tonic::Request::new(tokio_stream::wrappers::ReceiverStream::new(rx));
    req.metadata_mut().insert(proto::client::ACTOR_ID_HEADER, reg.actor_id.parse().unwrap());
    let mut acks = c.stream_experience(req).await.unwrap().into_inner();
    tx.send(batch(&reg.actor_id, 1, 0, 4)).await.unwrap();
    assert_eq!(acks.message().await.unwrap().unwrap().stored, 3);
    let a = actor(&status(&mut observer).await);
    assert!(a.connected && a.open_streams == 1, "{a:?}");

    // The connection goes away (as when the process is killed).
    drop((tx, acks, c));
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let a = actor(&status(&mut observer).await);
        if !a.connected {
            assert_eq!(a.open_streams, 0);
            assert!(a.last_seen_secs < 60.0, "disconnected by its closed stream, not by the timeout");
            break;
        }
        assert!(Instant::now() < deadline, "still connected after its connection closed: {a:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    running.stop().await.unwrap();
}

/// Issue row: "an env index beyond the registered count; seq going backwards; an empty batch:
/// accepted".
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn batches_out_of_place_in_the_stream_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, |_| {}).await;
    let mut c = client(&running.addr.to_string()).await;
    let reg = register(&mut c, "a", 2).await;
    let id = reg.actor_id.as_str();
    assert_eq!(send(&mut c, vec![batch(id, 10, 0, 5)]).await.unwrap()[0].stored, 4);
    let beyond = pb::ExperienceBatch { steps: vec![step(2, 0, 0)], ..batch(id, 11, 0, 0) };
    let cases = [
        (beyond, "env 2 is beyond the 2 environments this actor registered"),
        (batch(id, 9, 5, 3), "seq 9 does not follow 10"),
        (batch(id, 11, 3, 3), "env 0 goes back from episode 0, t 4 to episode 0, t 3"),
        (batch(id, 12, 0, 0), "has no steps; empty batches are refused"),
    ];
    for (b, text) in cases {
        let err = send(&mut c, vec![b]).await.unwrap_err();
        assert_eq!(err.code(), Code::InvalidArgument, "{err:?}");
        assert!(err.message().contains(text), "{}", err.message());
    }
    // Nothing of them was stored; the stream goes on where it was.
    assert_eq!(send(&mut c, vec![batch(id, 11, 5, 3)]).await.unwrap()[0].stored, 3);
    let st = status(&mut c).await;
    assert_eq!((st.batches_rejected, st.transitions_stored, st.replay_size), (4, 7, 7));
    running.stop().await.unwrap();
}

/// Copies a directory tree (a crash image: the files as they are now, with whatever was synced
/// or not).
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &target);
        } else if let Err(err) = std::fs::copy(e.path(), &target) {
            // A file that vanished meanwhile (a checkpoint swap): as if the crash came first.
            assert_eq!(err.kind(), std::io::ErrorKind::NotFound, "{err}");
        }
    }
}

/// Issue rows: "SIGKILL of the learner, then --resume: the replay buffer starts empty; actors with
/// a higher weights version keep their pre-crash weights" and "SIGKILL 45 s into a run: no
/// checkpoint exists". The run directory is copied while the learner runs, which is what the disk
/// holds after a SIGKILL at that moment; a learner resumes from the copy.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_crash_image_resumes_with_every_acknowledged_transition_and_newer_weights() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, |_| {}).await;
    let run = dir.path().join("run");
    // A crash right after the start: there is a checkpoint to resume.
    let early = tempfile::tempdir().unwrap();
    copy_tree(&run, &early.path().join("run"));
    let cfg = std::fs::read_to_string(dir.path().join("run.toml")).unwrap();
    std::fs::write(early.path().join("run.toml"), &cfg).unwrap();
    let resume_in = |image: &Path| ServeOptions {
        config: Some(image.join("run.toml")),
        run_dir: Some(image.join("run")),
        resume: true,
        ..ServeOptions::default()
    };
    let resumed = start(resume_in(early.path())).await;
    resumed.expect("a learner killed right after its start resumes").stop().await.unwrap();

    // Three acknowledged batches, each made durable before its acknowledgement; training runs and
    // publishes.
    let addr = running.addr.to_string();
    let mut c = client(&addr).await;
    let reg = register(&mut c, "a", 1).await;
    let acks = send(&mut c, (0..3).map(|k| batch(&reg.actor_id, k + 1, k as u32 * 40, 40)).collect()).await.unwrap();
    assert_eq!(acks.iter().map(|a| a.stored).sum::<u32>(), 119);
    assert!(acks.windows(2).all(|w| w[0].log_position < w[1].log_position) && acks[0].log_position > 0, "{acks:?}");
    let deadline = Instant::now() + Duration::from_secs(60);
    let before = loop {
        let st = status(&mut c).await;
        if st.weights_version >= 4 {
            break st;
        }
        assert!(Instant::now() < deadline, "no weights published: {st:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!((before.replay_size, before.durability.as_str()), (119, "ack"));
    assert!(before.replay_log_durable_position >= acks[2].log_position);
    let image = tempfile::tempdir().unwrap();
    copy_tree(&run, &image.path().join("run"));
    std::fs::write(image.path().join("run.toml"), &cfg).unwrap();
    running.stop().await.unwrap();

    let again = start(resume_in(image.path())).await.unwrap();
    let mut c = client(&again.addr.to_string()).await;
    let st = status(&mut c).await;
    assert_eq!(st.run_id, before.run_id);
    // The replay holds every acknowledged transition; the counters include the batches logged
    // after the checkpoint (the one written at the start).
    assert_eq!((st.replay_size, st.transitions_stored, st.transitions_received), (119, 119, 119));
    assert_eq!(st.replay_log_durable_position, acks[2].log_position);
    // Newer weights than anything published before the crash, served to an actor that holds the
    // pre-crash version on its next poll; its lag shows.
    assert!(st.weights_version > before.weights_version, "{} after {}", st.weights_version, before.weights_version);
    let reg = register(&mut c, "a", 1).await;
    let w = c
        .get_weights(pb::GetWeightsRequest { actor_id: reg.actor_id.clone(), have_version: before.weights_version })
        .await
        .unwrap()
        .into_inner();
    assert!(w.version == st.weights_version && !w.safetensors.is_empty());
    let lag = status(&mut c).await.actors.iter().find(|a| a.name == "a").unwrap().version_lag;
    assert_eq!(lag, st.weights_version - before.weights_version);
    // New batches continue the log.
    let ack = send(&mut c, vec![batch(&reg.actor_id, 1, 0, 2)]).await.unwrap();
    assert!(ack[0].log_position > acks[2].log_position);
    again.stop().await.unwrap();
}

/// Issue row: "a checkpoint or publish error inside training: the training thread returns Err and
/// stops; the server keeps accepting data and says nothing". A checkpoint that cannot be written
/// (a file where the checkpoint directory goes) is retried with backoff while training goes on,
/// and Status says why until it works again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_checkpoint_that_cannot_be_written_is_retried_and_shown() {
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path(), false, |cfg| cfg.service.checkpoint_interval_secs = 1).await;
    let ckpt = dir.path().join("run/checkpoint");
    std::fs::remove_dir_all(&ckpt).unwrap();
    std::fs::write(&ckpt, b"in the way").unwrap();
    let mut c = client(&running.addr.to_string()).await;
    let reg = register(&mut c, "a", 1).await;
    send(&mut c, vec![batch(&reg.actor_id, 1, 0, 60)]).await.unwrap();
    let observer = c.clone();
    let wait = |what: &'static str, ok: fn(&pb::StatusResponse) -> bool| {
        let mut c = observer.clone();
        async move {
            let deadline = Instant::now() + Duration::from_secs(60);
            loop {
                let st = status(&mut c).await;
                if ok(&st) {
                    return st;
                }
                assert!(Instant::now() < deadline, "{what}: {st:#?}");
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    };
    let st = wait("the failed checkpoint in Status", |s| !s.checkpoint_error.is_empty()).await;
    assert!(st.checkpoint_error.contains("renaming the new checkpoint into place"), "{}", st.checkpoint_error);
    assert!(st.training_error.is_empty());
    let step = st.learner_step;
    wait("training going on meanwhile", |s| s.learner_step > 0).await;
    assert!(send(&mut c, vec![batch(&reg.actor_id, 2, 60, 2)]).await.is_ok(), "still serving");
    // The obstacle goes: the retry succeeds and the error clears.
    std::fs::remove_file(&ckpt).unwrap();
    let st = wait("a checkpoint after the retry", |s| s.checkpoint_error.is_empty()).await;
    assert!(ckpt.join("manifest.json").exists());
    assert!(st.learner_step >= step);
    running.stop().await.unwrap();
}

/// Issue row: "a checkpoint with another action set or stack is refused, naming both": resuming
/// with a configuration whose action set or frame stack differs from the checkpoint's fails
/// before any weights load, naming the field and both values.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resuming_with_another_action_set_or_stack_is_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    start_tiny(dir.path(), false, |_| {}).await.stop().await.unwrap();
    let resume_with = |edit: &dyn Fn(&mut RunConfig)| {
        let mut cfg = RunConfig::tiny(&dir.path().join("run"));
        cfg.service.max_message_bytes = 1 << 20;
        edit(&mut cfg);
        let path = dir.path().join("other.toml");
        std::fs::write(&path, cfg.to_toml()).unwrap();
        ServeOptions { config: Some(path), resume: true, ..ServeOptions::default() }
    };
    let full = resume_with(&|c| c.agent.action_set = sim_core::actions::ActionSet::Full27);
    let Err(e) = start(full).await else { panic!("another action set is refused") };
    let e = format!("{e:#}");
    assert!(
        e.contains("agent.action_set: the checkpoint was trained with `paper6` (6 actions), this run is configured with `full27`"),
        "{e}"
    );
    let stacked = resume_with(&|c| c.env.camera.as_mut().unwrap().stack = 2);
    let Err(e) = start(stacked).await else { panic!("another stack is refused") };
    let e = format!("{e:#}");
    assert!(e.contains("env.camera.stack: the checkpoint sees 1 frame(s), this run is configured with 2"), "{e}");
    // The same configuration resumes.
    start(resume_with(&|_| {})).await.expect("the same configuration resumes").stop().await.unwrap();
}
