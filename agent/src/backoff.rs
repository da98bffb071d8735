//! Exponential backoff, the project's one: a wait that starts at `first`, doubles after every
//! failure up to `max`, and returns to `first` after a success. The actor waits with ±25 %
//! jitter between attempts to reach the learner (drawn from its seeded generator, so a run's
//! waits repeat), the learner without jitter between attempts to write a checkpoint. Pure
//! arithmetic on `Duration`s: the callers sleep.

use std::time::Duration;

use rand::{Rng, RngExt};

/// Waits between retries: `first`, doubling to at most `max`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Backoff {
    first: Duration,
    max: Duration,
    next: Duration,
}

impl Backoff {
    /// Starts at `first`, doubling up to `max`.
    #[must_use]
    pub const fn new(first: Duration, max: Duration) -> Self {
        Self { first, max, next: first }
    }

    /// The wait before the next attempt; the one after is twice as long, up to `max`.
    pub fn next_wait(&mut self) -> Duration {
        let wait = self.next;
        self.next = (self.next * 2).min(self.max);
        wait
    }

    /// [`next_wait`](Self::next_wait) times a factor drawn uniformly from [0.75, 1.25) (one draw
    /// from `rng`), so that many clients refused at once do not retry in step.
    pub fn next_wait_jittered(&mut self, rng: &mut impl Rng) -> Duration {
        let jitter: f64 = rng.random_range(0.75..1.25);
        Duration::from_secs_f64(self.next_wait().as_secs_f64() * jitter)
    }

    /// Back to `first` (after a success).
    pub fn reset(&mut self) {
        self.next = self.first;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn doubles_to_the_cap_and_resets() {
        let mut b = Backoff::new(Duration::from_secs(5), Duration::from_secs(300));
        let waits: Vec<u64> = (0..8).map(|_| b.next_wait().as_secs()).collect();
        assert_eq!(waits, [5, 10, 20, 40, 80, 160, 300, 300]);
        b.reset();
        assert_eq!(b.next_wait(), Duration::from_secs(5));
    }

    #[test]
    fn jitter_stays_within_a_quarter_and_repeats_with_the_seed() {
        let waits = |seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut b = Backoff::new(Duration::from_millis(500), Duration::from_secs(30));
            (0..10).map(|_| b.next_wait_jittered(&mut rng)).collect::<Vec<_>>()
        };
        let (a, again) = (waits(7), waits(7));
        assert_eq!(a, again);
        let mut plain = Backoff::new(Duration::from_millis(500), Duration::from_secs(30));
        for w in a {
            let base = plain.next_wait().as_secs_f64();
            assert!((0.75 * base..1.25 * base).contains(&w.as_secs_f64()), "{w:?} vs {base}");
        }
    }
}
