//! Policies the actor can drive with without a learner.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::actions::ActionSet;
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::vehicle::Action;

/// A driving policy.
#[derive(Debug, Clone)]
pub enum Policy {
    /// The model-based reference driver.
    Expert(Expert),
    /// Uniformly random actions of the paper's six, from a seeded stream.
    Random(Box<ChaCha8Rng>),
}

impl Policy {
    /// The policy named on the command line.
    pub fn from_name(name: &str, seed: u64) -> anyhow::Result<Self> {
        match name {
            "expert" => Ok(Self::Expert(Expert::default())),
            "random" => Ok(Self::Random(Box::new(ChaCha8Rng::seed_from_u64(seed ^ 0x5eed)))),
            other => anyhow::bail!("unknown policy `{other}`: expected `expert` or `random`"),
        }
    }

    /// The action for the environment's state.
    pub fn act(&mut self, env: &Env) -> Action {
        match self {
            Self::Expert(e) => e.act(env),
            Self::Random(rng) => {
                let actions = ActionSet::Paper6.actions();
                actions[(rng.next_u32() as usize) % actions.len()]
            }
        }
    }
}
