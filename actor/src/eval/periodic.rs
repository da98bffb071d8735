//! Greedy evaluation during training: the learner's current weights driven greedily on the seven
//! routes of a town, a few runs each, so that a run's metrics show when the agent first becomes
//! competent (not only its ε-greedy training returns).

use std::path::PathBuf;

use agent::config::RunConfig;
use anyhow::Result;
use sim_core::scenario::{EvalRoute, Scenario};
use sim_core::town::Town;

use super::report::Report;
use super::run::{Agent, Driver, EvalOptions, evaluate};
use crate::greedy::{CheckpointInfo, GreedyAgent};

/// Route types completed in at least this share of their runs count as mastered.
pub const MASTERED_SHARE: f64 = 0.5;

/// Evaluates `weights` of a run configured by `cfg` on the seven routes of `town`, `runs` runs
/// each (seeds `seed..seed + runs`), on one thread.
pub fn evaluate_weights(cfg: &RunConfig, weights: &[u8], town: &str, runs: u32, seed: u64) -> Result<Report> {
    let source = CheckpointInfo {
        weights: PathBuf::from("(the learner's current weights)"),
        run_dir: None,
        learner_step: None,
        env_steps: None,
        episodes: None,
    };
    let agent = GreedyAgent::from_weights(cfg.clone(), weights, 1, source)?;
    let mut agents = vec![Agent { name: "current".into(), driver: Driver::Greedy(Box::new(agent)) }];
    let town = Town::embedded(town).ok_or_else(|| anyhow::anyhow!("unknown town `{town}`"))?;
    let routes = EvalRoute::ALL.iter().map(|&r| (r.name(), Scenario::Eval(r))).collect();
    evaluate(&mut agents, &EvalOptions { routes, runs, seed, traffic: None, town, progress: false })
}

/// Route types completed in at least [`MASTERED_SHARE`] of their runs.
#[must_use]
pub fn route_types_mastered(report: &Report) -> usize {
    report.agents.first().map_or(0, |a| a.routes.iter().filter(|r| r.completion_rate >= MASTERED_SHARE).count())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::tiny_config;
    use sim_core::config::Variant;

    #[test]
    fn fresh_weights_are_evaluated_on_all_seven_routes() {
        let cfg = tiny_config(Variant::Hybrid);
        let weights = agent::weights::to_safetensors(&agent::fastnet::Params::init(cfg.net_shape(), 3), "").unwrap();
        let report = evaluate_weights(&cfg, &weights, "default_town", 1, 0).unwrap();
        assert_eq!(report.agents[0].routes.len(), 7);
        assert!(route_types_mastered(&report) <= 7);
        let e = evaluate_weights(&cfg, b"not weights", "default_town", 1, 0).unwrap_err();
        assert!(format!("{e:#}").contains("do not fit"), "{e:#}");
    }
}
