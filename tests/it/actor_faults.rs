//! The actor process against a learner that refuses its batches as too large, freezes, or
//! restarts: a learner in this process, the real `actor` binary, and a TCP proxy in between that
//! stops forwarding (what a SIGSTOPped learner looks like from the network) or that keeps one
//! address across the learner's restart.

use crate::support;

use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use support::{Process, Signal, actor, signal, status};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

async fn start_learner(dir: &Path, edit: impl FnOnce(&mut RunConfig)) -> Running {
    let mut cfg = RunConfig::tiny(&dir.join("run"));
    cfg.env.traffic.vehicles = 2;
    cfg.agent.min_replay = 5000;
    cfg.agent.replay_capacity = 5000;
    edit(&mut cfg);
    let path = dir.join("run.toml");
    std::fs::write(&path, cfg.to_toml()).unwrap();
    start(ServeOptions { config: Some(path), ..ServeOptions::default() }).await.unwrap()
}

fn spawn_actor(addr: &str, name: &str, batch_steps: u32, log: &Path) -> Process {
    support::spawn_actor(addr, name, &["--batch-steps", &batch_steps.to_string()], log)
}

/// Issue row: "learner with service.max_message_bytes = 1 MiB, a real actor with --batch-steps 200:
/// in 25 s, 0 transitions delivered, no warning anywhere, ~590 silent reconnects, ~590 actor
/// records". 200 steps of 84×84 RGB are ~4 MB: the actor must cut them below 1 MiB.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_actor_splits_its_batches_below_the_learners_message_limit() {
    let dir = tempfile::tempdir().unwrap();
    let learner = start_learner(dir.path(), |cfg| {
        cfg.service.max_message_bytes = 1 << 20;
        let cam = cfg.env.camera.as_mut().unwrap();
        (cam.width, cam.height, cam.rgb) = (84, 84, true);
    })
    .await;
    let addr = learner.addr.to_string();
    let log = dir.path().join("a.log");
    let mut a = spawn_actor(&addr, "a", 200, &log);
    let deadline = Instant::now() + Duration::from_secs(180);
    let s = loop {
        let s = status(&addr).await;
        if actor(&s, "a").is_some_and(|x| x.transitions >= 1000) {
            break s;
        }
        let _ = a.0.try_wait().map(|e| assert!(e.is_none(), "the actor exited: {e:?}\n{}", std::fs::read_to_string(&log).unwrap()));
        assert!(Instant::now() < deadline, "no transitions delivered: {s:#?}\n{}", std::fs::read_to_string(&log).unwrap());
        tokio::time::sleep(Duration::from_millis(300)).await;
    };
    let rec = actor(&s, "a").unwrap();
    assert_eq!((s.actors.len(), rec.registrations, rec.rejected_batches, s.batches_rejected), (1, 1, 0, 0), "{s:#?}");
    a.kill9();
    learner.stop().await.unwrap();
}

/// A TCP proxy to `target` that forwards until `frozen` is set, then holds every connection open
/// without forwarding a byte (new connections are accepted and held too), like a SIGSTOPped
/// process whose kernel still completes handshakes.
async fn freezable_proxy(target: String, frozen: Arc<AtomicBool>) -> String {
    proxy(Arc::new(std::sync::Mutex::new(target)), frozen).await
}

/// A TCP proxy to whatever address `target` holds when a connection arrives (a connection is
/// closed at once if nothing listens there): a learner's fixed address across its restarts.
async fn movable_proxy(target: Arc<std::sync::Mutex<String>>) -> String {
    proxy(target, Arc::new(AtomicBool::new(false))).await
}

/// The proxy of [`freezable_proxy`] and [`movable_proxy`]: its address.
async fn proxy(target: Arc<std::sync::Mutex<String>>, frozen: Arc<AtomicBool>) -> String {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    tokio::spawn(async move {
        loop {
            let Ok((client, _)) = listener.accept().await else { return };
            let to = target.lock().unwrap().clone();
            let Ok(server) = tokio::net::TcpStream::connect(&to).await else { continue };
            let (cr, cw) = client.into_split();
            let (sr, sw) = server.into_split();
            tokio::spawn(pump(cr, sw, frozen.clone()));
            tokio::spawn(pump(sr, cw, frozen.clone()));
        }
    });
    addr
}

/// Waits (up to 120 s) until the learner at `addr` has transitions from actor `name`.
async fn wait_until_streaming(addr: &str, name: &str, log: &Path) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while actor(&status(addr).await, name).is_none_or(|x| x.transitions == 0) {
        assert!(
            Instant::now() < deadline,
            "the actor never streamed:
{}",
            std::fs::read_to_string(log).unwrap()
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

async fn pump(mut from: tokio::net::tcp::OwnedReadHalf, mut to: tokio::net::tcp::OwnedWriteHalf, frozen: Arc<AtomicBool>) {
    let mut buf = vec![0u8; 64 << 10];
    loop {
        while frozen.load(Ordering::SeqCst) {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        match from.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => {
                while frozen.load(Ordering::SeqCst) {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
                if to.write_all(&buf[..n]).await.is_err() {
                    return;
                }
            }
        }
    }
}

/// Issue row: "learner frozen (SIGSTOP), actor Ctrl-C: the actor takes 27 s to exit instead of its
/// ~5 s flush". It exits within its flush deadline (5 s; the test allows 20 s for a loaded
/// machine, still below the 27 s it took) and says how many steps it could not send.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_actor_stops_within_its_flush_deadline_when_the_learner_is_frozen() {
    let dir = tempfile::tempdir().unwrap();
    let learner = start_learner(dir.path(), |_| {}).await;
    let frozen = Arc::new(AtomicBool::new(false));
    let proxy = freezable_proxy(learner.addr.to_string(), frozen.clone()).await;
    let log = dir.path().join("a.log");
    let mut a = spawn_actor(&proxy, "a", 16, &log);
    let addr = learner.addr.to_string();
    wait_until_streaming(&addr, "a", &log).await;
    frozen.store(true, Ordering::SeqCst);
    // Steps pile up in the actor's outbox, unacknowledged.
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert!(signal(a.pid(), Signal::INT));
    let asked = Instant::now();
    let code = loop {
        if let Some(code) = a.0.try_wait().unwrap() {
            break code;
        }
        assert!(
            asked.elapsed() < Duration::from_secs(20),
            "the actor has not exited 20 s after Ctrl-C:\n{}",
            std::fs::read_to_string(&log).unwrap()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(code.success(), "exit {code:?}:\n{text}");
    let line = text.lines().find(|l| l.contains("could not send")).unwrap_or_else(|| panic!("no account of the unsent steps:\n{text}"));
    assert!(line.contains("WARN") && line.contains("unsent_steps"), "{line}");
    frozen.store(false, Ordering::SeqCst);
    learner.stop().await.unwrap();
}

/// Found by the chaos test: after a learner restart, actors took up to 15.6 s to register again
/// (and so to show the new weights in Status), because the wait before reconnecting had grown
/// while the learner was down (0.5 s doubling to 30 s). The actor's weights poll, every second,
/// notices the learner answering again and cuts that wait short. Here the learner is away 17 s
/// (the wait has grown to 16 s ± 25 %) and the actor must be back within 6 s of its return.
/// (Without the poll's notice a grown wait can still end inside those 6 s by chance, about one
/// run in ten; checking the actor's log line for the notice made the test flaky for that reason.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_actor_registers_again_as_soon_as_a_restarted_learner_answers() {
    // Slow: the learner stays away 17 s on purpose, for the actor's wait to grow.
    if crate::slow::skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let first = start_learner(dir.path(), |_| {}).await;
    let target = Arc::new(std::sync::Mutex::new(first.addr.to_string()));
    let proxy = movable_proxy(target.clone()).await;
    let log = dir.path().join("a.log");
    let mut a = spawn_actor(&proxy, "a", 16, &log);
    let addr = first.addr.to_string();
    wait_until_streaming(&addr, "a", &log).await;
    first.stop().await.unwrap();
    tokio::time::sleep(Duration::from_secs(17)).await;
    let path = dir.path().join("run.toml");
    let second = start(ServeOptions { config: Some(path), resume: true, ..ServeOptions::default() }).await.unwrap();
    let addr = second.addr.to_string();
    *target.lock().unwrap() = addr.clone();
    let back = Instant::now();
    loop {
        if actor(&status(&addr).await, "a").is_some_and(|x| x.connected && x.transitions > 0) {
            break;
        }
        assert!(a.0.try_wait().unwrap().is_none(), "the actor exited:\n{}", std::fs::read_to_string(&log).unwrap());
        assert!(
            back.elapsed() < Duration::from_secs(6),
            "the actor is not streaming to the restarted learner 6 s after its return:\n{}",
            std::fs::read_to_string(&log).unwrap()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    a.kill9();
    second.stop().await.unwrap();
}

/// A token is never sent in clear to an address that is not loopback: the actor stops before
/// connecting, naming the flag that would allow it (192.0.2.1, TEST-NET-1, answers nothing: a
/// connection attempt would be retried for ever instead).
#[test]
fn an_actor_refuses_to_send_its_token_in_clear_off_loopback() {
    let dir = tempfile::tempdir().unwrap();
    let token = dir.path().join("token");
    std::fs::write(&token, "s3cret\n").unwrap();
    let out =
        Command::new(env!("CARGO_BIN_EXE_actor")).args(["--learner", "192.0.2.1:50051", "--auth-token-file"]).arg(&token).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("refusing to send the auth token in clear to 192.0.2.1") && stderr.contains("--insecure-plaintext"),
        "{stderr}"
    );
}
