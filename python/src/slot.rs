//! One environment as the binding drives it: a `sim_core::Env`, the scenario it resets to, and
//! the stream its episode seeds come from when `reset` gets no seed.
//!
//! `reset(Some(s))` starts the episode with seed `s` and restarts the stream from `s`;
//! `reset(None)` takes the stream's next seed. So a seed fixes every later episode too, and a
//! sub-environment of a vector env seeded `s + i` replays exactly what a single env does after
//! `reset(seed=s + i)` followed by unseeded resets.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::env::{Env, EnvError, Observation, StepResult};
use sim_core::scenario::Scenario;
use sim_core::vehicle::Action;

use crate::config::SimConfig;

#[derive(Debug, Clone)]
pub struct Slot {
    pub env: Env,
    pub scenario: Scenario,
    pub route: &'static str,
    seeds: ChaCha8Rng,
    episode_seed: u64,
}

impl Slot {
    /// An environment of `cfg`, reset with `seed`.
    pub fn new(cfg: &SimConfig, seed: u64) -> Result<Self, EnvError> {
        let env = Env::new(cfg.town.clone(), cfg.env.clone())?;
        let mut slot = Self { env, scenario: cfg.scenario, route: cfg.route, seeds: seed_stream(0), episode_seed: 0 };
        slot.reset(Some(seed))?;
        Ok(slot)
    }

    /// Starts an episode with `seed`, or with the stream's next seed.
    pub fn reset(&mut self, seed: Option<u64>) -> Result<Observation, EnvError> {
        self.episode_seed = match seed {
            Some(s) => {
                self.seeds = seed_stream(s);
                s
            }
            None => self.seeds.next_u64(),
        };
        self.env.reset(self.episode_seed, self.scenario)
    }

    pub fn step(&mut self, action: Action) -> Result<StepResult, EnvError> {
        self.env.step(action)
    }

    /// The seed of the current episode: `reset(seed=...)` with it replays the episode.
    pub fn episode_seed(&self) -> u64 {
        self.episode_seed
    }
}

/// The episode-seed stream of `seed`: ChaCha8 on stream 1, so that it does not repeat the draws of
/// the environment's own generator (stream 0 of the same seed).
fn seed_stream(seed: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(1);
    rng
}
