//! Demonstrators (`actor --learner ADDR --demonstrate NAME`): a planner drives, its controls
//! quantised to the run's action set (`ActionSet::nearest`, the rule of `actor eval`'s quantised
//! drivers), and its steps go to the learner as demonstrations (DQfD).
//!
//! The teacher may see what the agent does not: `model-based-avoid` plans with `astar+avoid`,
//! which knows the hazards, and the planner's path is part of the observation (d, the path
//! features, the vector sensor's path). So each environment has a twin, the teacher's: the same
//! run configuration, seed and actions, with the teacher's planner and no sensors. The planner
//! moves nothing in the world, so both stay in the same state (a test checks it); the teacher acts
//! in its twin, and the demonstration records the run's own environment: the observation and
//! reward the agent would have had.

use std::sync::Arc;

use agent::config::RunConfig;
use anyhow::Result;
use sim_core::actions::ActionSet;
use sim_core::env::{Env, StepResult};
use sim_core::expert::Expert;
use sim_core::planner::PlannerKind;
use sim_core::scenario::Scenario;
use sim_core::town::Town;
use sim_core::vehicle::Action;

/// The drivers a demonstrator can demonstrate with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Demonstrator {
    /// The reference driver with the `astar+avoid` planner: it sees the hazards.
    ModelBasedAvoid,
    /// The reference driver with the plain A\* planner: blind to the hazards.
    ModelBased,
}

impl Demonstrator {
    /// Every demonstrator, by name.
    pub const ALL: [Self; 2] = [Self::ModelBasedAvoid, Self::ModelBased];

    /// Its name on the command line, in Register and in Status (the names of `actor eval`'s
    /// baselines).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::ModelBasedAvoid => "model-based-avoid",
            Self::ModelBased => "model-based",
        }
    }

    /// The demonstrator named `name`.
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|d| d.name() == name)
            .ok_or_else(|| anyhow::anyhow!("unknown demonstrator `{name}`: expected {}", Self::ALL.map(Self::name).join(" or ")))
    }

    fn expert(self) -> Expert {
        match self {
            Self::ModelBasedAvoid => Expert::avoiding(),
            Self::ModelBased => Expert::default(),
        }
    }

    fn planner(self) -> PlannerKind {
        match self {
            Self::ModelBasedAvoid => PlannerKind::AstarAvoid,
            Self::ModelBased => PlannerKind::Astar,
        }
    }
}

/// The teacher's twins of an actor's environments.
#[derive(Debug)]
pub struct Teacher {
    envs: Vec<Env>,
    expert: Expert,
    set: ActionSet,
}

impl Teacher {
    /// `n` twins of the run's environments, for `who`.
    pub fn new(who: Demonstrator, cfg: &RunConfig, town: &Arc<Town>, n: usize) -> Result<Self> {
        let mut env = cfg.env.clone();
        env.planner = who.planner();
        // The teacher reads the world's ground truth: no pixels or readings to make.
        (env.camera, env.vector) = (None, None);
        let envs = (0..n).map(|_| Env::new(town.clone(), env.clone())).collect::<Result<_, _>>()?;
        Ok(Self { envs, expert: who.expert(), set: cfg.agent.action_set })
    }

    /// Starts twin `k`'s episode as the run's environment starts its own.
    pub fn reset(&mut self, k: usize, seed: u64, scenario: Scenario) -> Result<()> {
        self.envs[k].reset(seed, scenario)?;
        Ok(())
    }

    /// The index, in the run's action set, of the action nearest the teacher's controls.
    #[must_use]
    pub fn act(&self, k: usize) -> u32 {
        self.set.nearest(self.expert.act(&self.envs[k])) as u32
    }

    /// Moves twin `k` by `action` as the run's environment was moved.
    pub fn step(&mut self, k: usize, action: Action) -> Result<StepResult> {
        Ok(self.envs[k].step(action)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_core::hazards::HazardKind;

    /// A teacher's twin stays in its environment's state: ego pose and speed bit for bit, the
    /// episode's end on the same step, through hazard episodes in which the avoiding planner
    /// detours (its path differs from the run's, the world does not). The demonstrations of
    /// `model-based-avoid` pass a construction closure more often than the blind planner's do.
    #[test]
    fn the_twin_stays_in_the_runs_state_and_the_avoiding_teacher_passes_hazards() {
        let mut cfg = RunConfig::preset("hybrid-vector").unwrap();
        cfg.env.hazards = sim_core::hazards::HazardsConfig::only(HazardKind::Construction);
        let town = Town::default_town();
        let mut arrived = [0, 0];
        for (i, who) in Demonstrator::ALL.into_iter().enumerate() {
            let mut teacher = Teacher::new(who, &cfg, &town, 1).unwrap();
            let mut env = Env::new(town.clone(), cfg.env.clone()).unwrap();
            for seed in 0..4 {
                env.reset(seed, Scenario::Random).unwrap();
                teacher.reset(0, seed, Scenario::Random).unwrap();
                loop {
                    let a = teacher.act(0);
                    assert!((a as usize) < cfg.agent.action_set.actions().len());
                    let action = cfg.agent.action_set.actions()[a as usize];
                    let r = env.step(action).unwrap();
                    let t = teacher.step(0, action).unwrap();
                    let twin = &teacher.envs[0];
                    assert_eq!(
                        (env.ego.pos.x.to_bits(), env.ego.pos.y.to_bits(), env.ego.speed.to_bits(), env.ego.heading.to_bits()),
                        (twin.ego.pos.x.to_bits(), twin.ego.pos.y.to_bits(), twin.ego.speed.to_bits(), twin.ego.heading.to_bits()),
                        "{} seed {seed}",
                        who.name()
                    );
                    assert_eq!((r.terminated, r.truncated), (t.terminated, t.truncated));
                    if r.terminated || r.truncated {
                        arrived[i] += usize::from(r.info.arrived);
                        break;
                    }
                }
            }
        }
        assert!(arrived[0] > arrived[1], "arrivals past a construction closure: avoiding {} vs blind {}", arrived[0], arrived[1]);
        assert_eq!(Demonstrator::from_name("model-based").unwrap(), Demonstrator::ModelBased);
        assert!(Demonstrator::from_name("expert").unwrap_err().to_string().contains("model-based-avoid or model-based"));
    }
}
