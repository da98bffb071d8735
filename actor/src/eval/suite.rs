//! `actor eval --suite hazards|clean`: every agent scored the field's way (`score.rs`) on a
//! suite of scenarios, `--runs` seeded variations each (run k with seed S + k), in lockstep as
//! `actor eval` drives. `hazards`: one scenario per hazard kind, on random routes of the town with
//! room for it (different routes, trigger distances, speeds and traffic per seed); `clean`: the
//! seven evaluation routes without hazards, scored the same way, so that the two read side by side.
//!
//! Besides the checkpoints, two baselines: `model-based` (the A* route and today's controller:
//! it yields to the cars in its corridor and knows nothing of hazards) and `model-based-avoid`
//! (the `astar+avoid` planner and the same controller, which also brakes for walkers).

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use serde::Serialize;
use sim_core::actions::ActionSet;
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::hazards::{HazardKind, HazardsConfig, episodes};
use sim_core::planner::PlannerKind;
use sim_core::scenario::{EvalRoute, Scenario};

use crate::eval::behaviour::BehaviourWatch;
use crate::eval::episode::Episode;
use crate::eval::lockstep::{Agent, Driver, eval_env_config};
use crate::eval::policy::Policy;
use crate::eval::score::{Infraction, ProgressWatch, RunEnd, RunScore, score_run};
use crate::eval::table::{Align, write_table};
use crate::eval::trajectory::{Trajectory, TrajectoryRecorder};

/// A suite of scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Suite {
    Hazards,
    /// The hazard suite with every parameter drawn beyond training's ranges.
    HazardsRobust,
    Clean,
}

impl Suite {
    /// The suite named on the command line.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "hazards" => Ok(Self::Hazards),
            "hazards-robust" => Ok(Self::HazardsRobust),
            "clean" => Ok(Self::Clean),
            other => bail!("--suite `{other}`: expected `hazards`, `hazards-robust` or `clean`"),
        }
    }

    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Hazards => "hazards",
            Self::HazardsRobust => "hazards-robust",
            Self::Clean => "clean",
        }
    }
}

/// The hazard kinds the suite drives: every kind, one scenario each.
pub const SUITE_KINDS: [HazardKind; 7] = HazardKind::ALL;

/// The `model-based-avoid` baseline.
#[must_use]
pub fn model_based_avoid() -> Agent {
    Agent { name: "model-based-avoid".into(), driver: Driver::ModelBased(Policy::Expert(Expert::avoiding())) }
}

/// The planner an agent drives with.
fn planner_of(agent: &Agent) -> PlannerKind {
    match &agent.driver {
        Driver::ModelBased(p) if p.sees_hazards() => PlannerKind::AstarAvoid,
        Driver::ModelBased(_) => PlannerKind::Astar,
        Driver::Greedy(g) => g.cfg.env.planner,
    }
}

/// One scenario of a suite: its name, what episodes start from, and its hazards.
struct ScenarioSpec {
    name: &'static str,
    scenario: Scenario,
    hazard: Option<HazardKind>,
}

/// The suite's scenarios on `town`: every hazard kind; the clean suite's route types the town
/// has (a map file may lack some: `sim_core::route_types`).
fn scenarios(suite: Suite, town: &sim_core::town::Town) -> Vec<ScenarioSpec> {
    match suite {
        Suite::Hazards | Suite::HazardsRobust => {
            SUITE_KINDS.iter().map(|&k| ScenarioSpec { name: k.name(), scenario: Scenario::Random, hazard: Some(k) }).collect()
        }
        Suite::Clean => EvalRoute::ALL
            .iter()
            .filter(|r| r.endpoints_in(town).is_some())
            .map(|&r| ScenarioSpec { name: r.name(), scenario: Scenario::Eval(r), hazard: None })
            .collect(),
    }
}

/// What to evaluate.
#[derive(Debug, Clone)]
pub struct SuiteOptions {
    pub suite: Suite,
    pub runs: u32,
    pub seed: u64,
    pub traffic: Option<usize>,
    pub town: std::sync::Arc<sim_core::town::Town>,
    pub progress: bool,
    /// Keep every run's trajectory (`SuiteReport::trajectories`).
    pub trajectories: bool,
    /// The baselines drive with this action set's actions only (`--quantise`).
    pub quantise: Option<ActionSet>,
}

/// One scenario's scores for one agent.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioReport {
    pub scenario: &'static str,
    pub driving_score: f64,
    pub route_completion: f64,
    pub success_rate: f64,
    pub mean_return: f64,
    pub runs: Vec<RunScore>,
}

/// One agent over the suite.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteAgentReport {
    pub name: String,
    pub planner: &'static str,
    pub driving_score: f64,
    pub route_completion: f64,
    pub infraction_penalty: f64,
    pub success_rate: f64,
    /// Infractions over the route kilometres driven.
    pub infractions_per_km: f64,
    /// Count of each infraction kind over all runs.
    pub infractions: BTreeMap<&'static str, u32>,
    pub scenarios: Vec<ScenarioReport>,
}

/// `{"suite", "town", "runs", "quantise"?, "agents": [...]}`.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteReport {
    pub suite: &'static str,
    pub town: String,
    pub runs: u32,
    /// The action set the baselines' controls were quantised to (`--quantise`), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quantise: Option<&'static str>,
    pub agents: Vec<SuiteAgentReport>,
    /// Every run's trajectory, agent by agent and scenario by scenario, when asked for.
    #[serde(skip)]
    pub trajectories: Vec<Trajectory>,
}

fn mean(xs: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = xs.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// Scores every agent on every scenario of the suite.
pub fn evaluate_suite(agents: &mut [Agent], opts: &SuiteOptions) -> Result<SuiteReport> {
    if opts.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let specs = scenarios(opts.suite, &opts.town);
    if specs.is_empty() {
        bail!("{} has none of the clean suite's route types ({})", opts.town.map.name, EvalRoute::ALL.map(EvalRoute::name).join(", "));
    }
    if opts.progress && specs.len() < scenarios(opts.suite, &sim_core::town::Town::default_town()).len() {
        let missing: Vec<&str> = EvalRoute::ALL.iter().map(|r| r.name()).filter(|n| !specs.iter().any(|s| s.name == *n)).collect();
        eprintln!("{} has no route of type {}: left out of the suite", opts.town.map.name, missing.join(", "));
    }
    let started = Instant::now();
    let total = agents.len() * specs.len();
    let mut done = 0usize;
    let mut reports = Vec::new();
    let mut trajectories = Vec::new();
    for agent in agents.iter_mut() {
        let planner = planner_of(agent);
        let mut scenario_reports = Vec::new();
        for spec in &specs {
            let mut cfg = eval_env_config(agent.driver.body(), opts.traffic);
            cfg.planner = planner;
            if let Some(kind) = spec.hazard {
                cfg.hazards = HazardsConfig::only(kind);
                episodes::use_suite_episodes(&mut cfg);
                if opts.suite == Suite::HazardsRobust {
                    cfg.hazards = HazardsConfig::beyond_training(kind);
                }
            }
            let mut envs: Vec<Env> = (0..opts.runs)
                .map(|_| Env::new(opts.town.clone(), cfg.clone()))
                .collect::<Result<_, _>>()
                .context("creating the environments")?;
            let t = Instant::now();
            let (runs, recorded) = drive_scored(&mut agent.driver, &mut envs, opts.seed, spec.scenario, opts.trajectories)
                .with_context(|| format!("{} on {}", agent.name, spec.name))?;
            trajectories
                .extend(recorded.into_iter().zip(&envs).zip(&runs).map(|((rec, env), r)| rec.finish(env, &agent.name, spec.name, r)));
            let r = ScenarioReport {
                scenario: spec.name,
                driving_score: mean(runs.iter().map(|r| r.driving_score)),
                route_completion: mean(runs.iter().map(|r| r.route_completion)),
                success_rate: mean(runs.iter().map(|r| f64::from(u8::from(r.success)))),
                mean_return: mean(runs.iter().map(|r| r.ret)),
                runs,
            };
            done += 1;
            if opts.progress {
                let left = started.elapsed().as_secs_f64() / done as f64 * (total - done) as f64;
                eprintln!(
                    "eval [{done:>2}/{total}] {:<18} {:<20} driving score {:.2}, completion {:.2}, success {:.2}  ({:.1} s; about {left:.0} s left)",
                    agent.name,
                    spec.name,
                    r.driving_score,
                    r.route_completion,
                    r.success_rate,
                    t.elapsed().as_secs_f64()
                );
            }
            scenario_reports.push(r);
        }
        let all: Vec<&RunScore> = scenario_reports.iter().flat_map(|s| &s.runs).collect();
        let mut infractions: BTreeMap<&'static str, u32> = Infraction::ALL.iter().map(|i| (i.name(), 0)).collect();
        for i in all.iter().flat_map(|r| &r.infractions) {
            *infractions.entry(i.name()).or_default() += 1;
        }
        let km: f64 = all.iter().map(|r| r.km).sum();
        let count: u32 = infractions.values().sum();
        reports.push(SuiteAgentReport {
            name: agent.name.clone(),
            planner: planner.name(),
            driving_score: mean(all.iter().map(|r| r.driving_score)),
            route_completion: mean(all.iter().map(|r| r.route_completion)),
            infraction_penalty: mean(all.iter().map(|r| r.infraction_penalty)),
            success_rate: mean(all.iter().map(|r| f64::from(u8::from(r.success)))),
            infractions_per_km: if km > 0.0 { f64::from(count) / km } else { 0.0 },
            infractions,
            scenarios: scenario_reports,
        });
    }
    Ok(SuiteReport {
        suite: opts.suite.name(),
        town: opts.town.map.name.clone(),
        runs: opts.runs,
        quantise: opts.quantise.map(ActionSet::name),
        agents: reports,
        trajectories,
    })
}

/// Drives one run per environment (run k with seed `seed + k`) in lockstep, ending a run when it
/// is blocked, and scores each; with `trace`, also records where each drove (else no recorders).
fn drive_scored(
    driver: &mut Driver,
    envs: &mut [Env],
    seed: u64,
    scenario: Scenario,
    trace: bool,
) -> Result<(Vec<RunScore>, Vec<TrajectoryRecorder>)> {
    for (k, env) in envs.iter_mut().enumerate() {
        env.reset(seed + k as u64, scenario)?;
    }
    let n = envs.len();
    let mut episodes = vec![Episode::default(); n];
    let mut watches = vec![ProgressWatch::default(); n];
    let mut behaviours = vec![BehaviourWatch::default(); n];
    let mut recorders = if trace { vec![TrajectoryRecorder::default(); n] } else { Vec::new() };
    for (k, env) in envs.iter().enumerate() {
        behaviours[k].record(env);
        if let Some(t) = recorders.get_mut(k) {
            t.record(env);
        }
    }
    let mut ends: Vec<Option<RunEnd>> = vec![None; n];
    loop {
        let live: Vec<usize> = (0..n).filter(|&k| ends[k].is_none()).collect();
        if live.is_empty() {
            break;
        }
        let actions = driver.actions(envs, &live);
        for (&k, action) in live.iter().zip(actions) {
            let env = &mut envs[k];
            let r = env.step(action)?;
            episodes[k].record(&r);
            behaviours[k].record(env);
            if let Some(t) = recorders.get_mut(k) {
                t.record(env);
            }
            let length = env.route.length();
            let blocked = watches[k].record(r.info.progress * length, env.cfg.dt);
            if r.terminated || r.truncated || blocked {
                ends[k] = Some(RunEnd {
                    arrived: r.info.arrived,
                    collision: r.info.collision,
                    timed_out: r.truncated && !r.info.arrived,
                    blocked: blocked && !r.terminated,
                    right_of_way_violations: env.right_of_way_violations(),
                    progress: f64::from(r.info.progress),
                    route_length_m: f64::from(length),
                });
            }
        }
    }
    let scores = ends
        .into_iter()
        .zip(&episodes)
        .zip(envs.iter())
        .zip(behaviours)
        .enumerate()
        .map(|(k, (((end, ep), env), behaviour))| {
            let end = end.expect("every run ended");
            let (route_completion, infractions, infraction_penalty, driving_score, success, km) = score_run(&end);
            RunScore {
                seed: seed + k as u64,
                route_completion,
                infraction_penalty,
                driving_score,
                success,
                infractions,
                km,
                ret: ep.ret,
                steps: ep.steps,
                hazard: env.hazard.as_ref().map(|h| h.kind.name()),
                hazard_triggered: env.hazard.as_ref().is_some_and(|h| h.triggered),
                behaviour: behaviour.finish(),
            }
        })
        .collect();
    Ok((scores, recorders))
}

/// The readable table (or Markdown): one row per scenario and agent, then each agent overall.
#[must_use]
pub fn suite_table(report: &SuiteReport, markdown: bool) -> String {
    use std::fmt::Write;
    let header = ["scenario", "agent", "planner", "driving score", "completion", "penalty", "success", "infractions", "mean return"];
    let mut rows: Vec<[String; 9]> = Vec::new();
    let infractions_of = |runs: &[&RunScore]| -> String {
        let mut counts: BTreeMap<&str, u32> = BTreeMap::new();
        for i in runs.iter().flat_map(|r| &r.infractions) {
            *counts.entry(i.name()).or_default() += 1;
        }
        if counts.is_empty() { "—".to_owned() } else { counts.iter().map(|(k, v)| format!("{k} {v}")).collect::<Vec<_>>().join(", ") }
    };
    let Some(first) = report.agents.first() else { return String::new() };
    for (i, s0) in first.scenarios.iter().enumerate() {
        for (j, a) in report.agents.iter().enumerate() {
            let s = &a.scenarios[i];
            let runs: Vec<&RunScore> = s.runs.iter().collect();
            rows.push([
                if j == 0 || markdown { s0.scenario.to_owned() } else { String::new() },
                a.name.clone(),
                a.planner.to_owned(),
                format!("{:.2}", s.driving_score),
                format!("{:.2}", s.route_completion),
                format!("{:.2}", mean(s.runs.iter().map(|r| r.infraction_penalty))),
                format!("{:.2}", s.success_rate),
                infractions_of(&runs),
                format!("{:.1}", s.mean_return),
            ]);
        }
    }
    for (j, a) in report.agents.iter().enumerate() {
        let runs: Vec<&RunScore> = a.scenarios.iter().flat_map(|s| &s.runs).collect();
        rows.push([
            if j == 0 || markdown { "overall".to_owned() } else { String::new() },
            a.name.clone(),
            a.planner.to_owned(),
            format!("{:.2}", a.driving_score),
            format!("{:.2}", a.route_completion),
            format!("{:.2}", a.infraction_penalty),
            format!("{:.2}", a.success_rate),
            infractions_of(&runs),
            format!("{:.1}", mean(a.scenarios.iter().map(|s| s.mean_return))),
        ]);
    }
    let mut out = String::new();
    let (l, r) = (Align::Left, Align::Right);
    write_table(&mut out, header, [l, l, l, r, r, r, r, l, r], &rows, markdown);
    let _ = writeln!(
        out,
        "\nSuite `{}` on town `{}`, {} run(s) per scenario. Driving score = route completion × infraction penalty (CARLA leaderboard factors: pedestrian 0.50, vehicle 0.60, static 0.65, right of way 0.70, timeout 0.70; off-road and blocked end the run); success = arrival without infraction.",
        report.suite, report.town, report.runs
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::greedy::load_checkpoint;
    use crate::eval::lockstep::model_based;
    use crate::testing::{tiny_config, write_checkpoint};
    use sim_core::config::Variant;

    fn opts(suite: Suite, runs: u32) -> SuiteOptions {
        SuiteOptions {
            suite,
            runs,
            seed: 0,
            traffic: None,
            town: sim_core::town::Town::default_town(),
            progress: false,
            trajectories: false,
            quantise: None,
        }
    }

    #[test]
    fn the_hazard_suite_separates_the_blind_baseline_from_the_avoiding_one_and_has_the_documented_shape() {
        let mut agents = vec![model_based(), model_based_avoid()];
        let report = evaluate_suite(&mut agents, &opts(Suite::Hazards, 2)).unwrap();
        let v: serde_json::Value = serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap();
        assert_eq!((v["suite"].as_str(), v["town"].as_str(), v["runs"].as_u64()), (Some("hazards"), Some("default_town"), Some(2)));
        let agents = v["agents"].as_array().unwrap();
        assert_eq!(agents[0]["planner"], "astar");
        assert_eq!(agents[1]["planner"], "astar+avoid");
        for a in agents {
            for key in ["driving_score", "route_completion", "infraction_penalty", "success_rate"] {
                assert!(a[key].is_number(), "{key}");
            }
            assert!(a["infractions"]["pedestrian_collision"].is_number());
            let scenarios = a["scenarios"].as_array().unwrap();
            let names: Vec<&str> = scenarios.iter().map(|s| s["scenario"].as_str().unwrap()).collect();
            assert_eq!(names, SUITE_KINDS.map(HazardKind::name));
            for s in scenarios {
                for key in ["driving_score", "route_completion", "success_rate", "mean_return"] {
                    assert!(s[key].is_number(), "{key}");
                }
                let runs = s["runs"].as_array().unwrap();
                assert_eq!(runs.len(), 2);
                assert_eq!(runs[0]["hazard"], s["scenario"], "every run has its scenario's hazard");
            }
        }
        let (blind, avoid) = (&report.agents[0], &report.agents[1]);
        assert!(blind.driving_score < avoid.driving_score, "{} vs {}", blind.driving_score, avoid.driving_score);
        let ped = |a: &SuiteAgentReport| a.infractions["pedestrian_collision"];
        assert!(ped(blind) >= 1 && ped(avoid) == 0, "blind {} avoid {}", ped(blind), ped(avoid));
        let t = suite_table(&report, true);
        assert!(t.starts_with("| scenario | agent | planner | driving score |") && t.contains("stalled_car"), "{t}");
    }

    /// `--trajectories-out`'s records: one per run, the ego where the simulator had it, the
    /// stalled car standing still on the route; none unless asked for.
    #[test]
    fn trajectories_follow_each_run_and_show_the_stalled_car_where_the_route_meets_it() {
        let mut agents = vec![model_based(), model_based_avoid()];
        assert!(evaluate_suite(&mut agents, &opts(Suite::Hazards, 1)).unwrap().trajectories.is_empty());
        let report = evaluate_suite(&mut agents, &SuiteOptions { trajectories: true, ..opts(Suite::Hazards, 2) }).unwrap();
        assert_eq!(report.trajectories.len(), 2 * SUITE_KINDS.len() * 2, "agents × kinds × runs");
        for t in &report.trajectories {
            let a = report.agents.iter().find(|a| a.name == t.agent).unwrap();
            let r = a.scenarios.iter().find(|s| s.scenario == t.scenario).unwrap().runs.iter().find(|r| r.seed == t.seed).unwrap();
            assert_eq!(t.ego.len() as u32, r.steps + 1, "the reset and every step");
            assert_eq!(t.driving_score.to_bits(), r.driving_score.to_bits());
            assert_eq!(t.hazard, r.hazard);
            let start = t.route[0];
            assert!(
                (t.ego[0][0] - start[0]).hypot(t.ego[0][1] - start[1]) < 5.0,
                "starts at the route's origin: {:?} vs {start:?}",
                t.ego[0]
            );
        }
        let stalled = report.trajectories.iter().find(|t| t.scenario == "stalled_car" && t.agent == "model-based").unwrap();
        let car = |bodies: &[crate::eval::trajectory::Body]| bodies.iter().find(|b| b.kind == "hazard_car").unwrap().centre;
        assert_eq!(car(&stalled.bodies_start), car(&stalled.bodies_end), "a stalled car does not move");
        let p = stalled.hazard_point.unwrap();
        let c = car(&stalled.bodies_start);
        assert!((p[0] - c[0]).hypot(p[1] - c[1]) < 3.0, "the car stands at the hazard point: {c:?} vs {p:?}");
        assert!(stalled.bodies_start.iter().all(|b| b.kind != "traffic"), "traffic is drawn at the end only");
        let walker = report.trajectories.iter().find(|t| t.scenario == "pedestrian_crossing").unwrap();
        assert!(walker.bodies_start.iter().any(|b| b.kind == "walker") && walker.bodies_start.iter().any(|b| b.kind == "parked_car"));
    }

    /// Each run's behaviour around its hazard: the planner that sees the closure drives around it
    /// and back into its lane; the blind one stops short of it, in its lane; at the walker's
    /// crossing the avoiding driver is slower.
    #[test]
    fn behaviour_shows_who_left_the_lane_came_back_and_slowed_for_the_walker() {
        let mut agents = vec![model_based(), model_based_avoid()];
        let report = evaluate_suite(&mut agents, &opts(Suite::Hazards, 2)).unwrap();
        let runs = |a: usize, kind: &str| &report.agents[a].scenarios.iter().find(|s| s.scenario == kind).unwrap().runs;
        for r in runs(1, "construction") {
            let b = &r.behaviour;
            assert!(b.passed_hazard == Some(true) && b.back_on_route == Some(true) && b.max_abs_lateral_m > 2.0, "avoid: {b:?}");
        }
        for r in runs(0, "construction") {
            let b = &r.behaviour;
            assert!(b.passed_hazard == Some(false) && b.back_on_route == Some(false) && b.max_abs_lateral_m < 1.0, "blind: {b:?}");
        }
        let speed = |a: usize| runs(a, "pedestrian_crossing")[0].behaviour.speed_at_hazard_ms.expect("reached the crossing");
        assert!(speed(1) < speed(0), "avoid {} m/s, blind {} m/s", speed(1), speed(0));
        let clean = evaluate_suite(&mut agents, &opts(Suite::Clean, 1)).unwrap();
        let b = &clean.agents[0].scenarios[0].runs[0].behaviour;
        assert!(b.passed_hazard.is_none() && b.back_on_route.is_none() && b.speed_at_hazard_ms.is_none(), "no hazard: {b:?}");
    }

    #[test]
    fn the_clean_suite_scores_the_seven_routes_and_the_baselines_complete_them() {
        let mut agents = vec![model_based(), model_based_avoid()];
        let report = evaluate_suite(&mut agents, &opts(Suite::Clean, 1)).unwrap();
        for a in &report.agents {
            assert_eq!(a.scenarios.len(), 7);
            assert!(a.driving_score >= 0.95, "{}: {}", a.name, a.driving_score);
            assert!(a.scenarios.iter().all(|s| s.runs[0].hazard.is_none()));
        }
        assert!(Suite::from_name("meteor").unwrap_err().to_string().contains("`hazards`, `hazards-robust` or `clean`"));
    }

    #[test]
    fn the_clean_suite_on_a_map_file_drives_the_route_types_it_has() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../sim-core/tests/data/opendrive/Town01.xodr");
        let town = crate::eval::routes::town_by_name_or_file(path).unwrap();
        let mut agents = vec![model_based()];
        let report = evaluate_suite(&mut agents, &SuiteOptions { town, ..opts(Suite::Clean, 1) }).unwrap();
        let names: Vec<&str> = report.agents[0].scenarios.iter().map(|s| s.scenario).collect();
        assert_eq!(names, ["straight_urban", "sharp_curve", "right_turn", "left_turn"], "docs/MAP-FORMAT.md's list");
        assert!(report.agents[0].driving_score > 0.9, "{}", report.agents[0].driving_score);
    }

    #[test]
    fn a_checkpoint_of_today_evaluates_on_both_suites_with_its_planner() {
        let dir = tempfile::tempdir().unwrap();
        write_checkpoint(dir.path(), &tiny_config(Variant::Hybrid));
        for suite in [Suite::Hazards, Suite::HazardsRobust, Suite::Clean] {
            let agent = load_checkpoint(dir.path()).unwrap();
            let mut agents = vec![Agent { name: "fresh".into(), driver: Driver::Greedy(Box::new(agent)) }];
            let report = evaluate_suite(&mut agents, &opts(suite, 1)).unwrap();
            let a = &report.agents[0];
            assert_eq!(a.planner, "astar", "checkpoints so far plan with A*");
            assert!(a.driving_score.is_finite() && (0.0..=1.0).contains(&a.driving_score), "{}", a.driving_score);
            assert_eq!(a.scenarios.len(), if suite == Suite::Clean { EvalRoute::ALL.len() } else { SUITE_KINDS.len() });
            assert_eq!(report.suite, suite.name());
        }
    }
}
