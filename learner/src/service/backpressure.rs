//! Backpressure for the replay ratio. The training thread may do `replay_ratio / batch_size`
//! updates per stored transition and no more; where it is slower than the actors (a weak machine,
//! a large camera, many actors) the ratio was only a ceiling, and the run trained on less than
//! its configuration says. An experience stream therefore stores no batch while the learner owes
//! more than `service.update_lag_limit` updates: the actor's outbox fills, and its stepping thread
//! waits for room (`actor/src/sampling/outbox.rs`), so the run's updates per env step are what it asked for.
//!
//! Held streams sleep until something that can let them through happens, and go in the order
//! they were held. [`Backpressure`] is a FIFO turnstile (tokio's `Mutex`, whose waiters are
//! served in the order they came) in front of a [`Notify`]: only the stream at the front of the
//! queue waits for the learner; the others wait for the turnstile, so a hundred held streams
//! cost nothing while nothing changes. The training thread wakes the front stream when an update
//! brings the debt within the limit, and the learner does when it stops or fails or its training
//! thread ends. An admitted stream keeps the turnstile until its batch is stored, so the next
//! one looks at the debt that batch left: the learner owes at most the limit plus one batch.
//!
//! Why not a watch channel of the update count: it wakes every held stream on every update, to
//! find that all but one must wait again. Why not a semaphore of owed updates: what a batch costs
//! in updates depends on its size and on the rounding of [`Shared::updates_owed`], the one formula
//! the training thread paces itself by; permits would be a second bookkeeping of the same debt.
//!
//! [`Shared::updates_owed`]: crate::shared_state::Shared::updates_owed

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use tokio::sync::{Mutex, MutexGuard, Notify};

/// The replay ratio's gate for experience streams.
#[derive(Debug)]
pub struct Backpressure {
    /// `service.update_lag_limit > 0`: otherwise every stream goes through at once.
    on: bool,
    /// Held by the stream at the front of the queue, and by an admitted stream until its batch is
    /// stored.
    turnstile: Mutex<()>,
    /// Wakes the stream at the front when it may be let through.
    room: Notify,
    /// Streams waiting for the turnstile.
    queued: AtomicUsize,
    /// Streams (0 or 1) waiting at the front for the learner.
    at_front: AtomicUsize,
    /// Times a waiting stream woke.
    wakeups: AtomicU64,
}

/// The streams held now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Held {
    /// A stream at the front of the queue waits for the learner to catch up.
    pub waiting_for_learner: bool,
    /// Streams queued behind it (or behind a stream storing its batch).
    pub queued: usize,
}

/// A stream let through: the next held stream waits until this is dropped, once the batch is
/// stored (or refused).
#[derive(Debug)]
pub struct Admission<'a> {
    _turn: Option<MutexGuard<'a, ()>>,
    waited: Option<Duration>,
}

impl Admission<'_> {
    /// How long the stream was held, if it was.
    #[must_use]
    pub fn waited(&self) -> Option<Duration> {
        self.waited
    }
}

impl Backpressure {
    /// A gate that holds streams (`on`, with `service.update_lag_limit > 0`) or lets all through.
    #[must_use]
    pub fn new(on: bool) -> Self {
        Self {
            on,
            turnstile: Mutex::new(()),
            room: Notify::new(),
            queued: AtomicUsize::new(0),
            at_front: AtomicUsize::new(0),
            wakeups: AtomicU64::new(0),
        }
    }

    /// Returns once `may_go` says the stream may store its batch and every stream held before it
    /// has stored its own. `may_go` must turn true only through what calls [`Backpressure::wake`]
    /// or through the batches of admitted streams.
    pub async fn admit(&self, may_go: impl Fn() -> bool) -> Admission<'_> {
        if !self.on {
            return Admission { _turn: None, waited: None };
        }
        let arrived = Instant::now();
        // Held when another stream already waits for the learner, or when this one has to;
        // meeting a stream that is storing its batch is not being held.
        let behind_a_held_stream = self.at_front.load(Ordering::SeqCst) > 0;
        let turn = match self.turnstile.try_lock() {
            Ok(turn) => turn,
            Err(_) => {
                let turn = {
                    let _queued = Count::of(&self.queued);
                    self.turnstile.lock().await
                };
                self.wakeups.fetch_add(1, Ordering::Relaxed);
                turn
            }
        };
        let waited_for_learner = self.until(&may_go).await;
        Admission { _turn: Some(turn), waited: (behind_a_held_stream || waited_for_learner).then(|| arrived.elapsed()) }
    }

    /// Lets the stream at the front look again: an update brought the debt within the limit, or
    /// the learner is stopping or has failed, or its training thread ended.
    pub fn wake(&self) {
        self.room.notify_waiters();
    }

    /// Times a held stream woke (to count that nothing wakes while nothing changes).
    #[must_use]
    pub fn wakeups(&self) -> u64 {
        self.wakeups.load(Ordering::Relaxed)
    }

    /// The streams held now.
    #[must_use]
    pub fn held(&self) -> Held {
        Held { waiting_for_learner: self.at_front.load(Ordering::SeqCst) > 0, queued: self.queued.load(Ordering::SeqCst) }
    }

    /// Waits, holding the turnstile, until `may_go`; true if it had to.
    async fn until(&self, may_go: &impl Fn() -> bool) -> bool {
        let mut waited = false;
        loop {
            // Registered before looking, so that a wake between the look and the wait is not lost.
            let room = self.room.notified();
            if may_go() {
                return waited;
            }
            {
                let _front = Count::of(&self.at_front);
                room.await;
            }
            self.wakeups.fetch_add(1, Ordering::Relaxed);
            waited = true;
        }
    }
}

/// Counts a waiting stream for as long as it waits, also when its task is dropped meanwhile.
struct Count<'a>(&'a AtomicUsize);

impl<'a> Count<'a> {
    fn of(n: &'a AtomicUsize) -> Self {
        n.fetch_add(1, Ordering::SeqCst);
        Self(n)
    }
}

impl Drop for Count<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

#[cfg(test)]
mod tests {
    use std::net::SocketAddr;
    use std::path::Path;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::time::{Duration, Instant};

    use agent::config::RunConfig;
    use proto::v1 as pb;
    use proto::v1::learner_client::LearnerClient;
    use tonic::transport::Channel;

    use super::{Backpressure, Held};
    use crate::serve::{Running, ServeOptions, Trainer, start_with};
    use crate::shared_state::Shared;
    use crate::training::dqn::Dqn;

    /// Bytes of a frame of the tiny run's 16×16 gray camera.
    const FRAME: usize = 256;

    /// A learner that trains one update per 32 transitions and holds its streams while it owes
    /// more than 4; `trainer` decides when its training thread starts.
    async fn learner(dir: &Path, trainer: Trainer) -> Running {
        let mut cfg = RunConfig::tiny(&dir.join("run"));
        let a = &mut cfg.agent;
        (a.replay_ratio, a.batch_size, a.replay_capacity, a.min_replay) = (1.0, 32, 20_000, 64);
        cfg.service.update_lag_limit = 4;
        let cfg_path = dir.join("run.toml");
        std::fs::write(&cfg_path, cfg.to_toml()).unwrap();
        start_with(ServeOptions { config: Some(cfg_path), ..ServeOptions::default() }, trainer).await.unwrap()
    }

    /// Waits (on the training thread, not the runtime) until the learner stops or fails.
    fn until_stopped(shared: &Arc<Shared>) {
        while !shared.stopping() && shared.failure().is_none() {
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// An actor on its own connection: registers as `name` and sends `sizes.len()` batches of one
    /// episode (env 0) on one stream, of `sizes[k]` steps each. Returns the batches
    /// acknowledged, or the status that ended the stream.
    async fn actor(addr: SocketAddr, name: String, sizes: Vec<u32>) -> Result<usize, tonic::Status> {
        // Connects and registers as an actor does, trying again when an attempt fails or stalls:
        // among hundreds of simultaneous connections one can be refused or hang in its
        // handshake, which real actors survive by their retries.
        let (mut c, reg) = loop {
            let attempt = async {
                let Ok(mut c) = LearnerClient::<Channel>::connect(format!("http://{addr}")).await else { return None };
                let reg =
                    c.register(pb::RegisterRequest { name: name.clone(), envs: 1, protocol: pb::PROTOCOL, ..Default::default() }).await;
                Some(reg.map(|r| (c, r.into_inner())))
            };
            match tokio::time::timeout(Duration::from_secs(5), attempt).await {
                Ok(Some(Ok(done))) => break done,
                Ok(Some(Err(status))) if !matches!(status.code(), tonic::Code::Unknown | tonic::Code::Unavailable) => return Err(status),
                Ok(_) | Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
            }
        };
        let mut t0 = 0;
        let batches: Vec<_> = sizes
            .iter()
            .enumerate()
            .map(|(k, &n)| {
                let steps = (t0..t0 + n)
                    .map(|t| pb::Step {
                        t,
                        obs: Some(pb::Observation { image: vec![(t % 251) as u8; FRAME], d: 1.0, ..Default::default() }),
                        action: t % 6,
                        reward: 0.1,
                        ..Default::default()
                    })
                    .collect();
                t0 += n;
                pb::ExperienceBatch { actor_id: reg.actor_id.clone(), seq: k as u64 + 1, steps, weights_version: 1, ..Default::default() }
            })
            .collect();
        let mut acks = c.stream_experience(tokio_stream::iter(batches)).await?.into_inner();
        let mut acknowledged = 0;
        while acknowledged < sizes.len() {
            match acks.message().await? {
                Some(_) => acknowledged += 1,
                None => break,
            }
        }
        Ok(acknowledged)
    }

    /// Stores enough that the learner owes more than its limit while its training thread has
    /// not started: every batch after it is held.
    async fn put_the_learner_behind(addr: SocketAddr) {
        assert_eq!(actor(addr, "filler".into(), vec![200]).await.expect("the filler's batch is stored"), 1);
    }

    /// Waits until all `streams` are held: one waiting for the learner, the others queued behind it.
    async fn until_held(shared: &Shared, streams: usize) {
        let deadline = Instant::now() + Duration::from_secs(300);
        let all = Held { waiting_for_learner: true, queued: streams - 1 };
        while shared.backpressure.held() != all {
            assert!(Instant::now() < deadline, "{streams} streams were not all held: {:?}", shared.backpressure.held());
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    /// Waits until the streams of all `streams` actors are held, or of every actor that registered
    /// (but the filler), at least `min`, with no other registering for 5 s; returns how many. One of
    /// hundreds of loopback clients sometimes never completes its Register (it never reaches a
    /// stream, so the hold is not why); the test goes on without it.
    async fn until_registered_streams_held(shared: &Shared, streams: usize, min: usize) -> usize {
        let deadline = Instant::now() + Duration::from_secs(120);
        let mut last = (0, Instant::now());
        loop {
            let registered = shared.actors.lock().expect("actors lock").len() - 1;
            if registered != last.0 {
                last = (registered, Instant::now());
            }
            let held = shared.backpressure.held();
            let all_held = held.waiting_for_learner && held.queued + 1 == registered;
            if all_held && (registered == streams || (registered >= min && last.1.elapsed() > Duration::from_secs(5))) {
                return registered;
            }
            assert!(Instant::now() < deadline, "{registered} registered streams (at least {min} wanted) were not all held: {held:?}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    static TRAIN: AtomicBool = AtomicBool::new(false);

    /// Trains once `TRAIN` is set.
    fn trains_when_told(shared: &Arc<Shared>, dqn: Dqn, run_dir: &Path) -> anyhow::Result<Dqn> {
        while !TRAIN.load(Ordering::SeqCst) {
            if shared.stopping() {
                return Ok(dqn);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        crate::training::trainer::run(shared, dqn, run_dir)
    }

    /// Issue 52: a few hundred actors held by the replay ratio, each on its own connection. While
    /// nothing changes (the training thread has not started) no held stream wakes and Status
    /// answers promptly; once the learner trains, every actor's batches go through in turn (none
    /// starves), with a wake-up per hand-over rather than per poll, and Status shows each actor's
    /// held seconds. Latency is printed; the 1 s bound at p99 is the issue's, far above what an
    /// idle runtime needs even on a loaded machine and far below what a polling hold gave.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn hundreds_of_held_streams_sleep_until_the_learner_catches_up() {
        const ACTORS: usize = 300;
        const BATCHES: usize = 2;
        let dir = tempfile::tempdir().unwrap();
        let running = learner(dir.path(), trains_when_told).await;
        let (addr, shared) = (running.addr, running.shared.clone());
        put_the_learner_behind(addr).await;
        let actors: Vec<_> = (0..ACTORS).map(|k| tokio::spawn(actor(addr, format!("a{k}"), vec![16; BATCHES]))).collect();
        let held = until_registered_streams_held(&shared, ACTORS, ACTORS - ACTORS / 100).await;

        let mut c = LearnerClient::connect(format!("http://{addr}")).await.unwrap();
        let before = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
        let woken_before = shared.backpressure.wakeups();
        let mut latencies = Vec::new();
        let measuring = Instant::now();
        while latencies.len() < 100 && measuring.elapsed() < Duration::from_secs(60) {
            let t = Instant::now();
            c.status(pb::StatusRequest {}).await.unwrap();
            latencies.push(t.elapsed());
        }
        let woken = shared.backpressure.wakeups() - woken_before;
        let after = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
        latencies.sort();
        let at = |q: f64| latencies[((latencies.len() - 1) as f64 * q).round() as usize];
        println!(
            "{held} streams held, nothing changing: {woken} wake-ups of held streams over {} Status calls in {:.2} s; Status p50 {:?}, p99 {:?}",
            latencies.len(),
            measuring.elapsed().as_secs_f64(),
            at(0.5),
            at(0.99)
        );
        assert_eq!((after.learner_step, after.transitions_stored), (before.learner_step, before.transitions_stored), "nothing changed");
        assert_eq!(woken, 0, "held streams woke {woken} times while nothing changed");
        assert!(at(0.99) < Duration::from_secs(1), "Status p99 {:?} with {held} streams held", at(0.99));

        TRAIN.store(true, Ordering::SeqCst);
        let mut through = 0;
        for a in actors {
            // Every held actor's batches are stored; a client that never registered is dropped.
            if let Ok(done) = tokio::time::timeout(Duration::from_secs(60), a).await {
                assert_eq!(done.unwrap().expect("every actor's batches are stored"), BATCHES);
                through += 1;
            }
        }
        assert!(through >= held, "{through} actors' batches stored of {held} held");
        let woken = shared.backpressure.wakeups() - woken_before;
        let st = c.status(pb::StatusRequest {}).await.unwrap().into_inner();
        println!("training: {woken} wake-ups for {} batches let through, {} updates", through * BATCHES, st.learner_step);
        assert!(woken <= 2 * (through * BATCHES) as u64, "{woken} wake-ups for {} batches", through * BATCHES);
        // Every actor was held (all at once, above), and Status says so per actor.
        let held: Vec<_> = st.actors.iter().filter(|a| a.name != "filler").map(|a| a.held_secs).collect();
        assert_eq!(held.len(), through);
        assert!(held.iter().all(|&s| s > 0.0), "held seconds per actor: {held:?}");
        running.stop().await.unwrap();
    }

    /// Whatever holds a stream, a stopping learner releases every held stream at once with
    /// `UNAVAILABLE` (the actor keeps its batch and resends it), and so does a failed one.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_stopping_or_failed_learner_releases_every_held_stream() {
        const ACTORS: usize = 20;
        fn never_trains(shared: &Arc<Shared>, dqn: Dqn, _: &Path) -> anyhow::Result<Dqn> {
            until_stopped(shared);
            Ok(dqn)
        }
        for failing in [false, true] {
            let dir = tempfile::tempdir().unwrap();
            let running = learner(dir.path(), never_trains).await;
            let (addr, shared) = (running.addr, running.shared.clone());
            put_the_learner_behind(addr).await;
            let actors: Vec<_> = (0..ACTORS).map(|k| tokio::spawn(actor(addr, format!("a{k}"), vec![16]))).collect();
            until_held(&shared, ACTORS).await;
            let (expected, result) = if failing {
                shared.fail("injected: the disk went away");
                let outcomes = results(actors).await;
                ("has stopped training (injected: the disk went away)", (outcomes, running.stop().await.is_err()))
            } else {
                let stopping = running.stop();
                let (outcomes, stopped) = tokio::join!(results(actors), stopping);
                ("the learner is stopping", (outcomes, stopped.is_ok()))
            };
            let (outcomes, stop_as_expected) = result;
            assert!(stop_as_expected, "failing {failing}: stop() reports the failure, and only then");
            for o in outcomes {
                let status = o.expect_err("released with a refusal, not stored");
                assert_eq!(status.code(), tonic::Code::Unavailable, "{status:?}");
                assert!(status.message().contains(expected), "{}", status.message());
            }
            assert_eq!(shared.backpressure.held(), Held { waiting_for_learner: false, queued: 0 });
        }
    }

    /// Each task's result, in order.
    async fn results(tasks: Vec<tokio::task::JoinHandle<Result<usize, tonic::Status>>>) -> Vec<Result<usize, tonic::Status>> {
        let mut out = Vec::new();
        for t in tasks {
            out.push(t.await.expect("actor task"));
        }
        out
    }

    /// The gate alone, on one thread: streams held go through in the order they were held, a
    /// stream let through queues again behind the others, and nothing wakes until the gate is told
    /// that something changed.
    #[tokio::test(flavor = "current_thread")]
    async fn held_streams_go_in_the_order_they_were_held() {
        const STREAMS: usize = 5;
        let gate = Arc::new(Backpressure::new(true));
        // Batches the learner would allow now.
        let room = Arc::new(AtomicUsize::new(0));
        let order = Arc::new(std::sync::Mutex::new(Vec::new()));
        for k in 0..STREAMS {
            let (gate, room, order) = (gate.clone(), room.clone(), order.clone());
            tokio::spawn(async move {
                for _ in 0..2 {
                    let admission = gate.admit(|| room.load(Ordering::SeqCst) > 0).await;
                    assert!(admission.waited().is_some(), "stream {k} was held");
                    room.fetch_sub(1, Ordering::SeqCst);
                    order.lock().unwrap().push(k);
                }
            });
            // Each stream reaches the gate before the next is spawned.
            tokio::task::yield_now().await;
        }
        assert_eq!(gate.held(), Held { waiting_for_learner: true, queued: STREAMS - 1 });
        for _ in 0..100 {
            tokio::task::yield_now().await;
        }
        assert_eq!(gate.wakeups(), 0, "nothing changed, nothing woke");
        // Told without room: the stream at the front looks once and waits again.
        gate.wake();
        for _ in 0..10 {
            tokio::task::yield_now().await;
        }
        assert_eq!((gate.wakeups(), order.lock().unwrap().len()), (1, 0));
        for n in 1..=2 * STREAMS {
            room.fetch_add(1, Ordering::SeqCst);
            gate.wake();
            for _ in 0..10 {
                tokio::task::yield_now().await;
            }
            assert_eq!(order.lock().unwrap().len(), n, "one batch of room lets one stream through");
        }
        let expected: Vec<usize> = (0..STREAMS).chain(0..STREAMS).collect();
        assert_eq!(*order.lock().unwrap(), expected);
        assert_eq!(gate.held(), Held { waiting_for_learner: false, queued: 0 });
    }

    /// Off (`service.update_lag_limit = 0`), the gate holds nothing and counts nothing.
    #[tokio::test(flavor = "current_thread")]
    async fn an_open_gate_holds_nothing() {
        let gate = Backpressure::new(false);
        assert_eq!(gate.admit(|| false).await.waited(), None);
        assert_eq!(gate.wakeups(), 0);
    }
}
