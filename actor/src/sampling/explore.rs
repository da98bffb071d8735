//! Exploration of a learning actor's environments: ε-greedy, or ε-z-greedy (Dabney et al. 2021,
//! "Temporally-extended ε-greedy exploration"): with probability ε a random action is started and
//! held for n steps, n drawn from a zeta distribution P(n) ∝ n^−μ truncated at `ez_max_repeat`.
//! A hold ends early with its episode. Every draw comes from the actor's seeded stream; ε-greedy
//! draws exactly what the stepping thread drew before ε-z-greedy existed.

use agent::config::{AgentConfig, Exploration};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// Per environment, the random action held and the steps it is still held for.
#[derive(Debug, Clone)]
pub struct Explorer {
    /// Cumulative probabilities of the durations 1..=max (ε-z-greedy); empty for ε-greedy.
    durations: Vec<f64>,
    held: Vec<Option<(u32, u32)>>,
}

impl Explorer {
    /// The exploration `cfg` configures, for `n` environments.
    #[must_use]
    pub fn new(cfg: &AgentConfig, n: usize) -> Self {
        let durations = match cfg.exploration {
            Exploration::Epsilon => Vec::new(),
            Exploration::EzGreedy => zeta_cdf(cfg.ez_mu, cfg.ez_max_repeat),
        };
        Self { durations, held: vec![None; n] }
    }

    /// The action of environment `k` given the greedy one, with exploration rate `epsilon` over
    /// `actions` actions.
    pub fn choose(&mut self, k: usize, greedy: u32, epsilon: f32, actions: usize, rng: &mut ChaCha8Rng) -> u32 {
        if self.durations.is_empty() {
            return if rng.random::<f32>() < epsilon { rng.random_range(0..actions) as u32 } else { greedy };
        }
        if let Some((a, left)) = self.held[k] {
            self.held[k] = (left > 1).then(|| (a, left - 1));
            return a;
        }
        if rng.random::<f32>() >= epsilon {
            return greedy;
        }
        let a = rng.random_range(0..actions) as u32;
        let u = rng.random::<f64>();
        let n = 1 + self.durations.partition_point(|&c| c < u).min(self.durations.len() - 1) as u32;
        self.held[k] = (n > 1).then_some((a, n - 1));
        a
    }

    /// Environment `k`'s episode ended: nothing is held into the next.
    pub fn episode_ended(&mut self, k: usize) {
        self.held[k] = None;
    }
}

/// P(N ≤ n) for n = 1..=max under P(n) ∝ n^−μ.
fn zeta_cdf(mu: f32, max: u32) -> Vec<f64> {
    let weights: Vec<f64> = (1..=max.max(1)).map(|n| f64::from(n).powf(-f64::from(mu))).collect();
    let total: f64 = weights.iter().sum();
    let mut acc = 0.0;
    let mut cdf: Vec<f64> = weights
        .iter()
        .map(|w| {
            acc += w / total;
            acc
        })
        .collect();
    *cdf.last_mut().expect("at least one duration") = 1.0;
    cdf
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// ε-greedy draws what the stepping thread always drew: one uniform, and a second for the
    /// random action only when exploring.
    #[test]
    fn epsilon_greedy_draws_as_before() {
        let cfg = AgentConfig::default();
        let mut e = Explorer::new(&cfg, 2);
        let (mut a, mut b) = (ChaCha8Rng::seed_from_u64(9), ChaCha8Rng::seed_from_u64(9));
        for step in 0..1000 {
            let got = e.choose(step % 2, 5, 0.3, 6, &mut a);
            let want = if b.random::<f32>() < 0.3 { b.random_range(0..6usize) as u32 } else { 5 };
            assert_eq!(got, want);
        }
    }

    /// ε-z-greedy holds a random action for a zeta-distributed number of steps: with μ = 2 and a
    /// cap of 30, P(1) = 1/H where H = Σ_{n≤30} n^−2 ≈ 1.6122, so about 62 % of holds last one
    /// step and the mean hold is Σ n·n^−2/H = H_30/H ≈ 3.995/1.612 ≈ 2.48 steps (H_30 the
    /// harmonic number). Measured over 20 000 holds (ε = 1: every choice starts or continues one).
    #[test]
    fn ez_greedy_holds_for_zeta_durations_and_not_across_episodes() {
        let cfg = AgentConfig { exploration: Exploration::EzGreedy, ez_mu: 2.0, ez_max_repeat: 30, ..AgentConfig::default() };
        let mut e = Explorer::new(&cfg, 1);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (mut holds, mut steps, mut ones) = (0u32, 0u32, 0u32);
        while holds < 20_000 {
            let a = e.choose(0, 99, 1.0, 27, &mut rng);
            assert!(a < 27, "a random action, never the greedy one at ε = 1");
            let mut n = 1;
            while e.held[0].is_some() {
                assert_eq!(e.choose(0, 99, 1.0, 27, &mut rng), a, "held");
                n += 1;
            }
            assert!(n <= 30);
            holds += 1;
            steps += n;
            ones += u32::from(n == 1);
        }
        let h: f64 = (1..=30).map(|n| 1.0 / f64::from(n * n)).sum();
        let h30: f64 = (1..=30).map(|n| 1.0 / f64::from(n)).sum();
        let (p1, mean) = (f64::from(ones) / 20_000.0, f64::from(steps) / 20_000.0);
        assert!((p1 - 1.0 / h).abs() < 0.015, "P(1) {p1} vs {}", 1.0 / h);
        assert!((mean - h30 / h).abs() < 0.1, "mean hold {mean} vs {}", h30 / h);
        // An episode's end drops the hold; with ε = 0 nothing random happens.
        let mut e = Explorer::new(&cfg, 1);
        e.held[0] = Some((3, 5));
        e.episode_ended(0);
        assert_eq!(e.choose(0, 7, 0.0, 27, &mut rng), 7);
        // The same seed, the same choices.
        let run = |seed| {
            let mut e = Explorer::new(&cfg, 2);
            let mut r = ChaCha8Rng::seed_from_u64(seed);
            (0..500).map(|i| e.choose(i % 2, 0, 0.2, 27, &mut r)).collect::<Vec<_>>()
        };
        assert_eq!(run(4), run(4));
    }
}
