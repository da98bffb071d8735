//! The experience a synthetic actor streams in the ingest benches: valid 84×84 gray steps of
//! 200-step episodes, numbered as a real actor numbers them.

use proto::v1 as pb;

/// One synthetic actor's stream of batches.
#[derive(Debug)]
pub struct SyntheticActor {
    actor_id: String,
    frame: Vec<u8>,
    episode: u64,
    t: u32,
    seq: u64,
}

impl SyntheticActor {
    /// Steps of an episode; the last one is truncated.
    const EPISODE_STEPS: u32 = 200;

    /// The actor the learner registered as `actor_id`.
    #[must_use]
    pub fn new(actor_id: String) -> Self {
        Self { actor_id, frame: vec![100u8; 84 * 84], episode: 0, t: 0, seq: 0 }
    }

    /// The next batch of `steps` steps, with the next sequence number.
    pub fn next_batch(&mut self, steps: u32) -> pb::ExperienceBatch {
        let steps = (0..steps)
            .map(|_| {
                let s = pb::Step {
                    env: 0,
                    episode: self.episode,
                    t: self.t,
                    obs: Some(pb::Observation { image: self.frame.clone(), speed: 1.0, d: 0.5, path: Vec::new(), vector: Vec::new() }),
                    action: 1,
                    reward: 0.1,
                    terminated: false,
                    truncated: self.t == Self::EPISODE_STEPS - 1,
                };
                self.t += 1;
                if self.t == Self::EPISODE_STEPS {
                    (self.t, self.episode) = (0, self.episode + 1);
                }
                s
            })
            .collect();
        self.seq += 1;
        pb::ExperienceBatch {
            actor_id: self.actor_id.clone(),
            seq: self.seq,
            steps,
            weights_version: 1,
            epsilon: 1.0,
            ..Default::default()
        }
    }
}
