//! What an actor's stepping thread and its network tasks share: the bounded outbox of steps
//! waiting to be sent, the newest weights, and the counters and flags both sides read.

use std::collections::VecDeque;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64};

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
}

/// What the stepping thread and the network tasks share.
#[derive(Debug)]
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
    pub env_steps: AtomicU64,
    /// The id of the current registration (the weights poll names it).
    pub actor_id: Mutex<String>,
    /// Set by the weights poll when the learner answers again after failing to: a restarted
    /// learner is back, so a wait before registering again can end now.
    pub learner_back: AtomicBool,
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
            tracing::warn!(dropped = s.len(), "outbox full: oldest steps dropped");
        }
    }
}
