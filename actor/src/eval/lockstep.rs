//! Driving the agents under evaluation: every agent on every route, `runs` times each (run k
//! with seed S + k), in lockstep batches so that a checkpoint's network chooses for every
//! unfinished run in one forward pass; and summarising the episodes of a route.

use std::time::Instant;

use agent::config::RunConfig;
use anyhow::{Context, Result, bail};
use sim_core::config::{EnvConfig, Variant};
use sim_core::env::Env;
use sim_core::scenario::Scenario;
use sim_core::vehicle::Action;

use crate::eval::episode::Episode;
use crate::eval::greedy::{EPSILON, GreedyAgent, greedy_actions};
use crate::eval::policy::Policy;
use crate::eval::report::{AgentReport, Report, RouteResult};

/// A policy under evaluation.
#[derive(Debug)]
pub struct Agent {
    pub name: String,
    pub driver: Driver,
}

/// How an agent picks actions.
#[derive(Debug)]
pub enum Driver {
    /// The A\* planner followed by the reference controller (`actor drive --policy expert`).
    ModelBased(Policy),
    /// A Q-network from a checkpoint, greedy.
    Greedy(Box<GreedyAgent>),
}

impl Driver {
    /// The configuration of the agent's own body, for a checkpoint (see [`eval_env_config`]).
    #[must_use]
    pub fn body(&self) -> Option<&EnvConfig> {
        match self {
            Driver::ModelBased(_) => None,
            Driver::Greedy(g) => Some(&g.cfg.env),
        }
    }

    /// The actions for the runs `live` of `envs`, chosen in lockstep: the planner for each run, or
    /// the network for all of them in one forward pass.
    pub fn actions(&mut self, envs: &[Env], live: &[usize]) -> Vec<Action> {
        match self {
            Driver::ModelBased(policy) => live.iter().map(|&k| policy.act(&envs[k])).collect(),
            Driver::Greedy(agent) => {
                let refs: Vec<&Env> = live.iter().map(|&k| &envs[k]).collect();
                greedy_actions(agent, &refs).into_iter().map(|a| agent.actions[a as usize]).collect()
            }
        }
    }
}

/// The environment every agent is evaluated in: the `paper` preset's world, scored with the
/// paper's reward (hybrid variant), driven with the agent's own body — the vehicle, the camera
/// (with its stack) and the vector sensor of the checkpoint's configuration; its action set comes
/// with its network.
/// The baselines (`body` none) drive the default vehicle without a camera.
pub(crate) fn eval_env_config(body: Option<&EnvConfig>, traffic: Option<usize>) -> EnvConfig {
    let mut env = RunConfig::preset("paper").expect("the paper preset exists").env;
    env.variant = Variant::Hybrid;
    env.camera = body.and_then(|b| b.camera.clone());
    env.vector = body.and_then(|b| b.vector.clone());
    if let Some(b) = body {
        env.vehicle = b.vehicle;
    }
    if let Some(n) = traffic {
        env.traffic.vehicles = n;
    }
    env
}

/// What to evaluate and how.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    pub routes: Vec<(&'static str, Scenario)>,
    pub runs: u32,
    pub seed: u64,
    pub traffic: Option<usize>,
    /// The town driven (the default town, the held-out town or a map file).
    pub town: std::sync::Arc<sim_core::town::Town>,
    /// Report each route on stderr as it finishes.
    pub progress: bool,
}

/// The model-based baseline agent.
#[must_use]
pub fn model_based() -> Agent {
    Agent { name: "model-based".into(), driver: Driver::ModelBased(Policy::from_name("expert", 0).expect("the expert policy exists")) }
}

/// Evaluates every agent on every route.
pub fn evaluate(agents: &mut [Agent], opts: &EvalOptions) -> Result<Report> {
    if opts.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let town = opts.town.clone();
    let total = agents.len() * opts.routes.len();
    let started = Instant::now();
    let mut done = 0usize;
    let mut reports = Vec::new();
    for agent in agents.iter_mut() {
        let cfg = eval_env_config(agent.driver.body(), opts.traffic);
        let camera = cfg.camera.clone();
        let traffic_vehicles = cfg.traffic.vehicles;
        let mut envs: Vec<Env> =
            (0..opts.runs).map(|_| Env::new(town.clone(), cfg.clone())).collect::<Result<_, _>>().context("creating the environments")?;
        let mut routes = Vec::new();
        for &(route, scenario) in &opts.routes {
            let t = Instant::now();
            let episodes =
                drive_route(&mut agent.driver, &mut envs, opts.seed, scenario).with_context(|| format!("{} on {route}", agent.name))?;
            let r = summarise(route, scenario, &episodes);
            done += 1;
            if opts.progress {
                let left = started.elapsed().as_secs_f64() / done as f64 * (total - done) as f64;
                eprintln!(
                    "eval [{done:>2}/{total}] {:<16} {:<22} {}/{} completed, mean return {:>8.1}  ({:.1} s; about {:.0} s left)",
                    agent.name,
                    route,
                    r.completed,
                    r.runs,
                    r.mean_return,
                    t.elapsed().as_secs_f64(),
                    left
                );
            }
            routes.push(r);
        }
        let mean_return = routes.iter().map(|r| r.mean_return).sum::<f64>() / routes.len().max(1) as f64;
        let routes_completed_majority = routes.iter().filter(|r| 2 * r.completed > r.runs).count();
        let (kind, variant, checkpoint) = match &agent.driver {
            Driver::ModelBased(_) => ("model_based", None, None),
            Driver::Greedy(g) => ("checkpoint", Some(g.cfg.env.variant), Some(g.source.clone())),
        };
        reports.push(AgentReport {
            name: agent.name.clone(),
            kind,
            variant,
            checkpoint,
            camera: camera.map(|c| {
                let frames = if c.stack > 1 { format!(" x{} frames", c.stack) } else { String::new() };
                format!("{}x{} {}{frames}", c.width, c.height, if c.rgb { "rgb" } else { "gray" })
            }),
            epsilon: EPSILON,
            seed: opts.seed,
            traffic_vehicles,
            mean_return,
            routes_completed_majority,
            routes,
        });
    }
    Ok(Report { town: town.map.name.clone(), agents: reports })
}

/// Drives one run per environment on `scenario` (run k with seed `seed + k`) in lockstep, the
/// network choosing for every unfinished run at once.
fn drive_route(driver: &mut Driver, envs: &mut [Env], seed: u64, scenario: Scenario) -> Result<Vec<Episode>> {
    for (k, env) in envs.iter_mut().enumerate() {
        env.reset(seed + k as u64, scenario)?;
    }
    let mut episodes = vec![Episode::default(); envs.len()];
    loop {
        let live: Vec<usize> = (0..envs.len()).filter(|&k| !episodes[k].done).collect();
        if live.is_empty() {
            return Ok(episodes);
        }
        let actions = driver.actions(envs, &live);
        for (&k, action) in live.iter().zip(actions) {
            let r = envs[k].step(action)?;
            episodes[k].record(&r);
        }
    }
}

fn summarise(route: &'static str, scenario: Scenario, episodes: &[Episode]) -> RouteResult {
    let n = episodes.len() as f64;
    let mean = |f: &dyn Fn(&Episode) -> f64| episodes.iter().map(f).sum::<f64>() / n;
    let completed = episodes.iter().filter(|e| e.arrived).count() as u32;
    let collisions = episodes.iter().filter(|e| e.collision.is_some()).count() as u32;
    let paper = match scenario {
        Scenario::Eval(r) => Some(r.paper_scores()),
        Scenario::Random => None,
    };
    RouteResult {
        route,
        runs: episodes.len() as u32,
        mean_return: mean(&|e| e.ret),
        min_return: episodes.iter().map(|e| e.ret).fold(f64::INFINITY, f64::min),
        max_return: episodes.iter().map(|e| e.ret).fold(f64::NEG_INFINITY, f64::max),
        completed,
        completion_rate: f64::from(completed) / n,
        collisions,
        collision_rate: f64::from(collisions) / n,
        collision_kinds: episodes.iter().filter_map(|e| e.collision.map(|c| c.name())).collect(),
        mean_d: mean(&Episode::mean_d),
        mean_speed_kmh: mean(&|e| e.mean_speed() * 3.6),
        mean_steps: mean(&|e| f64::from(e.steps)),
        paper_hybrid_dqn: paper.map(|p| p.0),
        paper_human: paper.map(|p| p.1),
        run_returns: episodes.iter().map(|e| e.ret).collect(),
        run_completed: episodes.iter().map(|e| e.arrived).collect(),
    }
}
