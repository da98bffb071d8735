//! Greedy evaluation during training: the learner's current weights driven greedily on the seven
//! routes of a town, a few runs each, and — for a run that trains with hazards — on the hazard
//! suite, both scored the field's way (`suite.rs`). A run's metrics then show when the agent first
//! becomes competent (not only its ε-greedy training returns), and `best/` keeps the weights that
//! scored highest (`best.rs`).

use std::path::PathBuf;

use agent::config::RunConfig;
use anyhow::Result;
use sim_core::town::Town;

use crate::eval::greedy::{CheckpointInfo, GreedyAgent};
use crate::eval::lockstep::{Agent, Driver};
use crate::eval::suite::{Suite, SuiteAgentReport, SuiteOptions, evaluate_suite};

/// Route types completed in at least this share of their runs count as mastered.
pub const MASTERED_SHARE: f64 = 0.5;

/// Seeds of the periodic evaluations, `SEED..SEED + runs`: validation seeds, apart from those of
/// `actor eval` (0.. by default, and in `scripts/reproduce.sh`), so that the weights chosen by
/// them are judged on runs that did not choose them.
pub const SEED: u64 = 10_000;

/// One periodic evaluation's scores.
#[derive(Debug, Clone)]
pub struct PeriodicScore {
    /// The seven routes (`--suite clean`).
    pub clean: SuiteAgentReport,
    /// The hazard suite, when asked for.
    pub hazards: Option<SuiteAgentReport>,
}

impl PeriodicScore {
    /// What `best/` is chosen by: the mean of the suites' driving scores.
    #[must_use]
    pub fn selection_score(&self) -> f64 {
        match &self.hazards {
            Some(h) => 0.5 * (self.clean.driving_score + h.driving_score),
            None => self.clean.driving_score,
        }
    }

    /// Route types completed (route completion 1) in at least [`MASTERED_SHARE`] of their runs.
    #[must_use]
    pub fn route_types_mastered(&self) -> usize {
        self.clean.scenarios.iter().filter(|s| completed(&s.runs) as f64 >= MASTERED_SHARE * s.runs.len() as f64).count()
    }

    /// Runs of the seven routes that arrived, over all of them.
    #[must_use]
    pub fn completion_rate(&self) -> f64 {
        let all: Vec<_> = self.clean.scenarios.iter().flat_map(|s| &s.runs).collect();
        all.iter().filter(|r| r.route_completion >= 1.0).count() as f64 / all.len().max(1) as f64
    }

    /// The mean over the seven routes of their mean return.
    #[must_use]
    pub fn mean_return(&self) -> f64 {
        mean(self.clean.scenarios.iter().map(|s| s.mean_return))
    }

    /// Per route: its name, the runs that arrived, its mean return.
    #[must_use]
    pub fn routes(&self) -> Vec<(&'static str, usize, f64)> {
        self.clean.scenarios.iter().map(|s| (s.scenario, completed(&s.runs), s.mean_return)).collect()
    }
}

fn completed(runs: &[crate::eval::score::RunScore]) -> usize {
    runs.iter().filter(|r| r.route_completion >= 1.0).count()
}

fn mean(xs: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = xs.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// Scores `weights` of a run configured by `cfg` on `town`: the seven routes and, with
/// `hazards`, the hazard suite, `runs` runs per route or kind (seeds `seed..seed + runs`), on one
/// thread.
pub fn score_weights(cfg: &RunConfig, weights: &[u8], town: &str, runs: u32, seed: u64, hazards: bool) -> Result<PeriodicScore> {
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
    let mut suite = |suite| -> Result<SuiteAgentReport> {
        let opts =
            SuiteOptions { suite, runs, seed, traffic: None, town: town.clone(), progress: false, trajectories: false, quantise: None };
        let mut report = evaluate_suite(&mut agents, &opts)?;
        Ok(report.agents.remove(0))
    };
    let clean = suite(Suite::Clean)?;
    let hazards = if hazards { Some(suite(Suite::Hazards)?) } else { None };
    Ok(PeriodicScore { clean, hazards })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::tiny_config;
    use sim_core::config::Variant;

    #[test]
    fn fresh_weights_are_scored_on_the_seven_routes_and_on_the_hazards_when_asked() {
        let cfg = tiny_config(Variant::Hybrid);
        let weights = agent::weights::to_safetensors(&agent::fastnet::Params::init(cfg.net_shape(), 3), "").unwrap();
        let clean = score_weights(&cfg, &weights, "default_town", 1, SEED, false).unwrap();
        assert_eq!(clean.clean.scenarios.len(), 7);
        assert!(clean.hazards.is_none());
        assert!(clean.route_types_mastered() <= 7);
        assert_eq!(clean.selection_score(), clean.clean.driving_score);
        assert_eq!(clean.routes().len(), 7);
        assert!((0.0..=1.0).contains(&clean.completion_rate()));
        let both = score_weights(&cfg, &weights, "default_town", 1, SEED, true).unwrap();
        let h = both.hazards.as_ref().expect("the hazard suite was asked for");
        assert_eq!(h.scenarios.len(), 7);
        assert_eq!(both.selection_score(), 0.5 * (both.clean.driving_score + h.driving_score));
        // The same weights and seeds: the same scores.
        assert_eq!(both.clean.driving_score, clean.clean.driving_score);
        let e = score_weights(&cfg, b"not weights", "default_town", 1, SEED, false).unwrap_err();
        assert!(format!("{e:#}").contains("do not fit"), "{e:#}");
    }
}
