//! What an actor's stepping thread and its network tasks share: the bounded outbox of steps
//! waiting to be sent, the newest weights, and the counters and flags both sides read.

use std::collections::VecDeque;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use agent::fastnet::Params;
use proto::v1 as pb;

/// A batch waiting in the outbox: its steps, the episodes they ended, the ε and the weights
/// version they were taken with.
pub type OutBatch = (Vec<pb::Step>, Vec<pb::EpisodeSummary>, f32, u64);

/// Steps waiting to be sent, bounded.
#[derive(Debug, Default)]
pub struct Outbox {
    pub batches: VecDeque<OutBatch>,
    pub steps: usize,
    pub dropped: u64,
    /// Overflow is reported at most once per [`DROP_WARN_EVERY`], with a count: while the learner
    /// is away the outbox overflows at every batch.
    last_drop_warning: Option<Instant>,
    dropped_unreported: u64,
}

/// How often an overflowing outbox says so.
pub const DROP_WARN_EVERY: Duration = Duration::from_secs(60);

/// What the stepping thread and the network tasks share (`default()`: nothing sent, not yet
/// connected).
#[derive(Debug, Default)]
pub struct Link {
    pub outbox: Mutex<Outbox>,
    /// Newest weights fetched, decoded and not yet acted with: (version, parameters). Decoded by
    /// the weights task, so that the stepping thread only swaps them in.
    pub fresh_weights: Mutex<Option<(u64, Params)>>,
    /// Version the policy acts with.
    pub acting_version: AtomicU64,
    pub stop: AtomicBool,
    /// The stepping thread has ended and handed over its last steps.
    pub stepper_done: AtomicBool,
    pub connected: AtomicBool,
    /// Environment steps this process has taken.
    pub env_steps: AtomicU64,
    /// The run's environment steps minus this process's, as of the learner's last report
    /// (`Register`, every weights poll): `env_steps` plus it is the run's step that the ε schedule
    /// follows, so that a restarted actor or a resumed run does not explore from scratch.
    pub run_steps_offset: AtomicI64,
    /// The id of the current registration (the weights poll names it).
    pub actor_id: Mutex<String>,
    /// Set by the weights poll when the learner answers again after failing to: a restarted
    /// learner is back, so a wait before registering again can end now.
    pub learner_back: AtomicBool,
    /// When the learner last acknowledged a batch.
    pub last_ack: Mutex<Option<Instant>>,
    /// Microseconds the stepping thread has waited for room in the outbox.
    pub waited_micros: AtomicU64,
    /// A demonstrator pauses while set: the run's demonstrations have caught up with its learning
    /// actors' steps (`pace_loop`).
    pub demo_pause: AtomicBool,
}

/// Batches the outbox may hold before the stepping thread waits for the learner to take some.
pub const ROOM_BATCHES: usize = 4;

/// A learner counts as taking batches while it acknowledged one this recently. One that holds
/// its streams for the replay ratio acknowledges every few updates; a frozen or lost one stops,
/// and the actor steps on (buffering, then dropping the oldest steps, as for an absent learner).
pub const ACK_FRESH: Duration = Duration::from_secs(5);

impl Link {
    /// Records the learner's count of the run's environment steps (0 from a learner that does not
    /// report it, which leaves the schedule on this process's own steps).
    pub fn note_run_env_steps(&self, run_env_steps: u64) {
        if run_env_steps > 0 {
            let own = self.env_steps.load(Ordering::SeqCst);
            self.run_steps_offset.store(run_env_steps as i64 - own as i64, Ordering::SeqCst);
        }
    }

    /// Waits while a connected learner that is taking batches has more than [`ROOM_BATCHES`]
    /// waiting: a learner that holds its streams for the replay ratio (`service.update_lag_limit`)
    /// slows the stepping instead of making it drop steps. Returns at once on stop, and when the
    /// learner is away or has acknowledged nothing for [`ACK_FRESH`].
    pub fn wait_for_room(&self) {
        let started = Instant::now();
        let mut waited = false;
        while !self.stop.load(Ordering::SeqCst)
            && self.connected.load(Ordering::SeqCst)
            && self.outbox.lock().expect("outbox lock").batches.len() > ROOM_BATCHES
            && self.last_ack.lock().expect("ack time lock").is_some_and(|t| t.elapsed() < ACK_FRESH)
        {
            waited = true;
            std::thread::sleep(Duration::from_millis(1));
        }
        if waited {
            self.waited_micros.fetch_add(started.elapsed().as_micros() as u64, Ordering::Relaxed);
        }
    }

    /// Records an acknowledgement from the learner.
    pub fn note_ack(&self) {
        *self.last_ack.lock().expect("ack time lock") = Some(Instant::now());
    }

    /// The run's environment step that this process's `own_steps` correspond to.
    pub fn run_env_steps(&self, own_steps: u64) -> u64 {
        (own_steps as i64 + self.run_steps_offset.load(Ordering::SeqCst)).max(0) as u64
    }
}

impl Outbox {
    /// Queues a batch, then drops the oldest batches while over `limit` steps — never the front
    /// one, which may be in flight, nor the newest — counting what was dropped.
    pub fn push_bounded(&mut self, batch: OutBatch, limit: usize) {
        self.steps += batch.0.len();
        self.batches.push_back(batch);
        while self.steps > limit && self.batches.len() > 2 {
            let (s, _, _, _) = self.batches.remove(1).expect("more than two batches");
            self.steps -= s.len();
            self.dropped += s.len() as u64;
            self.dropped_unreported += s.len() as u64;
        }
        if self.dropped_unreported > 0 && self.last_drop_warning.is_none_or(|t| t.elapsed() >= DROP_WARN_EVERY) {
            let since = self.last_drop_warning.map_or_else(String::new, |t| format!(" in the last {:.0} s", t.elapsed().as_secs_f64()));
            tracing::warn!(
                dropped = self.dropped_unreported,
                dropped_total = self.dropped,
                "outbox full (the learner is not taking steps): {} oldest steps dropped{since} (said at most once a minute)",
                self.dropped_unreported
            );
            self.dropped_unreported = 0;
            self.last_drop_warning = Some(Instant::now());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link() -> Link {
        Link { connected: AtomicBool::new(true), ..Link::default() }
    }

    /// The stepping thread waits while a learner that is taking batches has more than
    /// `ROOM_BATCHES` waiting, until it takes one; not for a learner that has acknowledged
    /// nothing lately (frozen, or gone: the outbox buffers and drops as before), nor once stopped.
    #[test]
    fn stepping_waits_for_room_only_while_the_learner_is_taking_batches() {
        let batch = || -> OutBatch { (vec![pb::Step::default(); 4], Vec::new(), 0.1, 1) };
        let link = std::sync::Arc::new(link());
        for _ in 0..=ROOM_BATCHES {
            link.outbox.lock().unwrap().push_bounded(batch(), 1000);
        }
        // Nothing acknowledged yet: no wait.
        link.wait_for_room();
        assert_eq!(link.waited_micros.load(Ordering::Relaxed), 0);
        // A learner taking batches: the wait ends when it takes one.
        link.note_ack();
        let taker = {
            let link = link.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(50));
                link.outbox.lock().unwrap().batches.pop_front();
                link.note_ack();
            })
        };
        link.wait_for_room();
        taker.join().unwrap();
        assert!(link.waited_micros.load(Ordering::Relaxed) >= 40_000, "waited {} µs", link.waited_micros.load(Ordering::Relaxed));
        assert_eq!(link.outbox.lock().unwrap().batches.len(), ROOM_BATCHES);
        // A stale acknowledgement (a frozen learner), or a stop: no wait.
        link.outbox.lock().unwrap().push_bounded(batch(), 1000);
        *link.last_ack.lock().unwrap() = Instant::now().checked_sub(ACK_FRESH);
        let before = link.waited_micros.load(Ordering::Relaxed);
        link.wait_for_room();
        link.note_ack();
        link.stop.store(true, Ordering::SeqCst);
        link.wait_for_room();
        assert_eq!(link.waited_micros.load(Ordering::Relaxed), before);
    }

    #[test]
    fn overflow_drops_the_oldest_but_the_front_and_counts_them() {
        let batch = |n: usize| -> OutBatch { (vec![pb::Step::default(); n], Vec::new(), 0.1, 1) };
        let mut ob = Outbox::default();
        for _ in 0..10 {
            ob.push_bounded(batch(4), 8);
        }
        assert_eq!(ob.batches.len(), 2);
        assert_eq!(ob.steps, 8);
        assert_eq!(ob.dropped, 32);
        // Reported once (the first overflow), the rest counted for the next report.
        assert!(ob.last_drop_warning.is_some());
        assert_eq!(ob.dropped_unreported, 28);
    }
}
