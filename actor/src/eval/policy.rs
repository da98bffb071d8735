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
    /// Another policy with every control replaced by the nearest action of a set
    /// (`ActionSet::nearest`): the most that set lets that policy's driving keep.
    Quantised(Box<Policy>, ActionSet),
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

    /// This policy, driving with `set`'s actions only.
    #[must_use]
    pub fn quantised(self, set: ActionSet) -> Self {
        Self::Quantised(Box::new(self), set)
    }

    /// Whether it perceives hazards (the `model-based-avoid` driver, drives with `astar+avoid`).
    #[must_use]
    pub fn sees_hazards(&self) -> bool {
        match self {
            Self::Expert(e) => e.sees_hazards,
            Self::Random(_) => false,
            Self::Quantised(p, _) => p.sees_hazards(),
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
            Self::Quantised(policy, set) => set.actions()[set.nearest(policy.act(env))],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_core::config::EnvConfig;
    use sim_core::scenario::Scenario;
    use sim_core::town::Town;

    #[test]
    fn a_quantised_policy_drives_with_the_sets_actions_only_and_keeps_what_it_sees() {
        let mut env = Env::new(Town::default_town(), EnvConfig { camera: None, ..EnvConfig::default() }).unwrap();
        env.reset(3, Scenario::Random).unwrap();
        let mut expert = Policy::from_name("expert", 0).unwrap();
        let mut quantised = expert.clone().quantised(ActionSet::Full15);
        let (mut differ, mut steps) = (0, 0);
        while !env.is_done() && steps < 100 {
            let (q, e) = (quantised.act(&env), expert.act(&env));
            assert!(ActionSet::Full15.actions().contains(&q), "{q:?}");
            differ += usize::from(q != e);
            env.step(q).unwrap();
            steps += 1;
        }
        assert!(differ > 0, "the expert's continuous controls are not all in the set");
        assert!(Policy::Expert(Expert::avoiding()).quantised(ActionSet::Paper6).sees_hazards());
        assert!(!expert.quantised(ActionSet::Paper6).sees_hazards());
    }
}
