//! `actor eval`: the paper's Table I. Each checkpoint is driven greedily (ε = 0: always the action
//! of highest Q, ties to the lowest index) on the seven evaluation routes, `--runs` times each
//! with different traffic (run k uses seed S + k), beside the model-based baseline — the A\*
//! planner followed by the reference controller, the `expert` of `actor drive`. Per route and
//! agent: the average cumulative reward (the paper's metric), completion and collision rates,
//! mean d, mean speed and steps, with the paper's Table I figures as a reference.
//!
//! A checkpoint describes itself: its `config.toml` gives the camera, the network, the action set
//! and the variant (whether d is an input). Every agent drives in the same conditions (the
//! `paper` preset's environment, its traffic unless `--traffic`, the evaluation time limit) and
//! is scored with the same reward, the paper's (r_w included): the paper used its training reward
//! as the evaluation metric, and one scale keeps the end-to-end agent's numbers comparable — it
//! still never sees d.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;

pub mod behaviour;
pub mod episode;
pub mod greedy;
pub mod lockstep;
pub mod policy;
pub mod report;
pub mod routes;
pub mod score;
pub mod suite;
pub mod table;
pub mod trajectory;

use greedy::{EPSILON, GreedyAgent, load_checkpoint};
use lockstep::{Agent, Driver, EvalOptions, evaluate, model_based};
use report::table;
use routes::{parse_routes, town_by_name_or_file};
use suite::{Suite, SuiteOptions, evaluate_suite, model_based_avoid, suite_table};

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A checkpoint: a run directory (of `actor train` or `learner serve`), its `checkpoint/`
    /// directory, its `best/` directory (the weights `actor train`'s periodic evaluations scored
    /// highest), or the `online.safetensors` in either. Repeat for several agents.
    #[arg(long, value_name = "PATH")]
    pub checkpoint: Vec<PathBuf>,
    /// Names of the checkpoints in the table, in the order of --checkpoint (default: the run
    /// directory's name).
    #[arg(long, value_name = "NAME")]
    pub name: Vec<String>,
    /// Runs per route; run k uses seed S + k (different traffic).
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Base seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Routes: `all` seven, or names separated by commas (straight_highway, straight_urban,
    /// straight_under_bridge, slight_curve, sharp_curve, right_turn, left_turn).
    #[arg(long, default_value = "all")]
    pub route: String,
    /// The town: `default_town` (the one agents train on), `held_out_town` (a second layout no
    /// training run sees, with its own seven routes of the same types) or a map file.
    #[arg(long, default_value = "default_town", value_name = "NAME|FILE")]
    pub town: String,
    /// Moving traffic cars (default: the paper preset's, 20).
    #[arg(long)]
    pub traffic: Option<usize>,
    /// Print one JSON object on the last line of stdout instead of the table.
    #[arg(long, conflicts_with = "markdown")]
    pub json: bool,
    /// Print the table as Markdown.
    #[arg(long)]
    pub markdown: bool,
    /// Also write the JSON object to this file.
    #[arg(long, value_name = "FILE")]
    pub json_out: Option<PathBuf>,
    /// Score the field's way (driving score = route completion × infraction penalty) on a suite:
    /// `hazards` (one scenario per hazard kind, on random routes of the town), `hazards-robust`
    /// (the same with every hazard parameter drawn beyond the ranges training draws from:
    /// docs/EVALUATION.md) or `clean` (the seven routes, those the town has), beside the
    /// `model-based` and `model-based-avoid` baselines. `--route` does not apply.
    #[arg(long, value_name = "SUITE")]
    pub suite: Option<String>,
    /// With --suite: write every run's trajectory to this file, one JSON object per line (agent,
    /// scenario, seed, the route's centre line, the ego's `[x, y, speed]` at every step, the
    /// hazard's objects at the start and the end, infractions, driving score), for pictures such
    /// as docs/figures/hazards-episode.svg (`scripts/episode_figure.py`).
    #[arg(long, value_name = "FILE", requires = "suite")]
    pub trajectories_out: Option<PathBuf>,
    /// With --suite: the baselines drive with this action set only, every control replaced by
    /// its nearest action (`paper6`, `paper12`, `full15`, `full21`, `full27`; docs/EVALUATION.md): the ceiling of a
    /// set, what its actions let a driver that knows how to drive keep.
    #[arg(long, value_name = "SET", requires = "suite", value_parser = parse_action_set)]
    pub quantise: Option<sim_core::actions::ActionSet>,
}

fn parse_action_set(name: &str) -> std::result::Result<sim_core::actions::ActionSet, String> {
    sim_core::actions::ActionSet::from_name(name)
}

/// The name of a checkpoint in the table: its run directory's name.
fn default_name(agent: &GreedyAgent, path: &Path) -> String {
    let named = agent.source.run_dir.as_deref().unwrap_or(path);
    let canonical = named.canonicalize().unwrap_or_else(|_| named.to_owned());
    canonical.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// `actor eval`.
pub fn run(args: &EvalArgs) -> Result<()> {
    if args.name.len() > args.checkpoint.len() {
        bail!("{} --name given for {} --checkpoint: give at most one name per checkpoint", args.name.len(), args.checkpoint.len());
    }
    if let Some(name) = &args.suite {
        return run_suite(args, name);
    }
    let mut routes = Vec::new();
    for name in args.route.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        routes.extend(parse_routes(name)?);
    }
    if routes.is_empty() {
        bail!("--route `{}` names no route", args.route);
    }
    let mut agents = vec![model_based()];
    add_checkpoints(args, &mut agents)?;
    let town = town_by_name_or_file(&args.town)?;
    let routes = routes_on(&town, routes)?;
    let opts = EvalOptions { routes, runs: args.runs, seed: args.seed, traffic: args.traffic, town, progress: true };
    eprintln!(
        "evaluating {} agent(s) on {} route(s) of {} × {} run(s) (seeds {}..={}), greedy (ε = {EPSILON})",
        agents.len(),
        opts.routes.len(),
        opts.town.map.name,
        opts.runs,
        opts.seed,
        opts.seed + u64::from(opts.runs.max(1) - 1)
    );
    let report = evaluate(&mut agents, &opts)?;
    emit(args, &serde_json::to_string(&report)?, || table(&report, args.markdown))
}

/// Writes a report where the flags say: `--json-out` (atomically), then the JSON line on stdout
/// with `--json`, else the table.
fn emit(args: &EvalArgs, json: &str, table: impl FnOnce() -> String) -> Result<()> {
    if let Some(path) = &args.json_out {
        agent::atomic_write::write_atomic(path, json.as_bytes(), None)?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{}", table());
    }
    Ok(())
}

/// The checkpoints of `--checkpoint` as agents after `agents`, each under a unique name.
fn add_checkpoints(args: &EvalArgs, agents: &mut Vec<Agent>) -> Result<()> {
    for (k, path) in args.checkpoint.iter().enumerate() {
        let agent = load_checkpoint(path)?;
        let mut name = args.name.get(k).cloned().unwrap_or_else(|| default_name(&agent, path));
        let base = name.clone();
        let mut n = 2;
        while agents.iter().any(|a| a.name == name) {
            name = format!("{base}#{n}");
            n += 1;
        }
        agents.push(Agent { name, driver: Driver::Greedy(Box::new(agent)) });
    }
    Ok(())
}

/// `actor eval --suite`.
fn run_suite(args: &EvalArgs, name: &str) -> Result<()> {
    let suite = Suite::from_name(name)?;
    let mut agents = vec![model_based(), model_based_avoid()];
    if let Some(set) = args.quantise {
        for a in &mut agents {
            let Driver::ModelBased(p) = &mut a.driver else { unreachable!("the baselines drive a policy") };
            *p = p.clone().quantised(set);
        }
        eprintln!("the baselines' controls are quantised to the {} actions of `{}`", set.actions().len(), set.name());
    }
    add_checkpoints(args, &mut agents)?;
    let town = town_by_name_or_file(&args.town)?;
    let opts = SuiteOptions {
        suite,
        runs: args.runs,
        seed: args.seed,
        traffic: args.traffic,
        town,
        progress: true,
        trajectories: args.trajectories_out.is_some(),
        quantise: args.quantise,
    };
    eprintln!(
        "scoring {} agent(s) on suite `{}` of {} × {} run(s) (seeds {}..), greedy (ε = {EPSILON})",
        agents.len(),
        suite.name(),
        opts.town.map.name,
        opts.runs,
        opts.seed
    );
    let report = evaluate_suite(&mut agents, &opts)?;
    if let Some(path) = &args.trajectories_out {
        let mut lines = String::new();
        for t in &report.trajectories {
            lines.push_str(&serde_json::to_string(t)?);
            lines.push('\n');
        }
        agent::atomic_write::write_atomic(path, lines.as_bytes(), None)
            .with_context(|| format!("writing the trajectories to {}", path.display()))?;
        eprintln!("wrote {} trajectories to {}", report.trajectories.len(), path.display());
    }
    emit(args, &serde_json::to_string(&report)?, || suite_table(&report, args.markdown))
}

/// The routes `town` has: a map without named places has the route types found in it by shape
/// (`sim_core::route_types`); the others are named and left out.
fn routes_on(
    town: &sim_core::town::Town,
    routes: Vec<(&'static str, sim_core::scenario::Scenario)>,
) -> Result<Vec<(&'static str, sim_core::scenario::Scenario)>> {
    use sim_core::scenario::Scenario;
    let has = |s: &Scenario| match s {
        Scenario::Eval(r) => r.endpoints_in(town).is_some(),
        Scenario::Random => true,
    };
    let (found, missing): (Vec<_>, Vec<_>) = routes.into_iter().partition(|(_, s)| has(s));
    if !missing.is_empty() {
        let names: Vec<&str> = missing.iter().map(|(n, _)| *n).collect();
        eprintln!("{} has no route of type {}: left out of the table", town.map.name, names.join(", "));
    }
    anyhow::ensure!(!found.is_empty(), "{} has none of the requested route types", town.map.name);
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{tiny_config, write_checkpoint};
    use sim_core::config::Variant;
    use sim_core::scenario::{EvalRoute, Scenario};

    fn opts(routes: &[EvalRoute], runs: u32) -> EvalOptions {
        EvalOptions {
            town: sim_core::town::Town::default_town(),
            routes: routes.iter().map(|&r| (r.name(), Scenario::Eval(r))).collect(),
            runs,
            seed: 0,
            traffic: None,
            progress: false,
        }
    }

    #[test]
    fn a_fresh_checkpoint_evaluates_beside_the_baseline_and_the_json_has_the_documented_shape() {
        let dir = tempfile::tempdir().unwrap();
        let run_dir = dir.path().join("hybrid-run");
        write_checkpoint(&run_dir, &tiny_config(Variant::Hybrid));
        let agent = load_checkpoint(&run_dir).unwrap();
        assert_eq!((agent.source.learner_step, agent.source.episodes), (Some(7), Some(9)));
        assert_eq!(default_name(&agent, &run_dir), "hybrid-run");
        let mut agents = vec![model_based(), Agent { name: "fresh".into(), driver: Driver::Greedy(Box::new(agent)) }];
        let report = evaluate(&mut agents, &opts(&[EvalRoute::SharpCurve], 1)).unwrap();
        let v: serde_json::Value = serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap();
        let agents = v["agents"].as_array().unwrap();
        assert_eq!(agents.len(), 2);
        assert_eq!(agents[0]["name"], "model-based");
        assert_eq!(agents[1]["name"], "fresh");
        assert_eq!(agents[1]["variant"], "hybrid");
        for a in agents {
            let routes = a["routes"].as_array().unwrap();
            assert_eq!(routes.len(), 1);
            assert_eq!(routes[0]["route"], "sharp_curve");
            for key in ["mean_return", "completion_rate", "collision_rate", "mean_d", "mean_speed_kmh", "mean_steps"] {
                assert!(routes[0][key].is_number(), "{key} missing in {}", routes[0]);
            }
            assert_eq!(routes[0]["paper_hybrid_dqn"].as_f64().unwrap() as f32, -74.4);
        }
        // The baseline completes the route (as `actor drive --policy expert` does).
        let expert = &report.agents[0].routes[0];
        assert_eq!((expert.completed, expert.collisions, expert.completion_rate), (1, 0, 1.0));
        assert!(expert.mean_return > 0.0 && expert.mean_speed_kmh > 5.0, "{expert:?}");
        // The table shows the paper's figure as a reference.
        let t = table(&report, false);
        assert!(t.contains("sharp_curve") && t.contains("-74.4") && t.contains("-8.9"), "{t}");
        let md = table(&report, true);
        assert!(md.lines().next().unwrap().starts_with("| route | agent | mean return |"), "{md}");
    }

    #[test]
    fn the_held_out_town_is_a_name_and_the_report_says_which_town() {
        let town = town_by_name_or_file("held_out_town").unwrap();
        let mut agents = vec![model_based()];
        let report = evaluate(&mut agents, &EvalOptions { town, ..opts(&[EvalRoute::LeftTurn], 1) }).unwrap();
        assert_eq!(report.town, "held_out_town");
        assert_eq!(report.agents[0].routes[0].completed, 1, "the baseline drives the held-out town's left turn");
        let e = town_by_name_or_file("no_such_town").unwrap_err().to_string();
        assert!(e.contains("default_town, held_out_town"), "{e}");
    }

    #[test]
    fn evaluation_is_deterministic_and_does_not_depend_on_batching() {
        let dir = tempfile::tempdir().unwrap();
        write_checkpoint(dir.path(), &tiny_config(Variant::EndToEnd));
        let weights = dir.path().join("checkpoint").join("online.safetensors");
        let run = |runs: u32| {
            let agent = load_checkpoint(&weights).unwrap();
            assert_eq!(agent.cfg.net_shape().scalars, 1, "end-to-end: speed only");
            let mut agents = vec![Agent { name: "e2e".into(), driver: Driver::Greedy(Box::new(agent)) }];
            evaluate(&mut agents, &opts(&[EvalRoute::StraightUrban], runs)).unwrap().agents.remove(0).routes.remove(0)
        };
        let (one, two) = (run(1), run(2));
        // Run 0 of a batch of two is the lone run of a batch of one: rows of a batch are
        // independent and each run's traffic comes from its own seed.
        assert_eq!(one.min_return.to_bits(), one.max_return.to_bits());
        assert!(two.min_return.to_bits() == one.mean_return.to_bits() || two.max_return.to_bits() == one.mean_return.to_bits());
        // Runs are listed in seed order: run 0 of two is the lone run of one.
        assert_eq!((one.run_returns.len(), two.run_returns.len(), two.run_completed.len()), (1, 2, 2));
        assert_eq!(two.run_returns[0].to_bits(), one.run_returns[0].to_bits());
        assert!((two.run_returns.iter().sum::<f64>() / 2.0 - two.mean_return).abs() < 1e-9);
        assert_eq!(run(1).mean_return.to_bits(), one.mean_return.to_bits());
    }

    #[test]
    fn a_hybrid_checkpoint_with_path_features_sees_them() {
        let dir = tempfile::tempdir().unwrap();
        let mut cfg = tiny_config(Variant::Hybrid);
        cfg.agent.path_features = true;
        write_checkpoint(dir.path(), &cfg);
        let agent = load_checkpoint(dir.path()).unwrap();
        assert_eq!(agent.cfg.net_shape().scalars, 5, "speed, d and three path features");
        let mut agents = vec![Agent { name: "hybrid".into(), driver: Driver::Greedy(Box::new(agent)) }];
        let row = evaluate(&mut agents, &opts(&[EvalRoute::RightTurn], 1)).unwrap().agents.remove(0).routes.remove(0);
        assert!(row.mean_return.is_finite() && row.mean_steps > 0.0, "{row:?}");
    }
}
