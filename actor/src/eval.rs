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
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use learner::config::RunConfig;
use learner::fastnet::Inference;
use serde::Serialize;
use sim_core::camera::CameraConfig;
use sim_core::config::{EnvConfig, Variant};
use sim_core::env::Env;
use sim_core::scenario::Scenario;
use sim_core::vehicle::Action;

use crate::drive::{Episode, load_town, parse_routes};
use crate::policy::Policy;

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A checkpoint: a run directory (of `actor train` or `learner serve`), its `checkpoint/`
    /// directory, or the `online.safetensors` in it. Repeat for several agents.
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
}

/// The exploration rate of evaluation: none, the greedy policy.
pub const EPSILON: f32 = 0.0;

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

/// A checkpoint's Q-network and the configuration it was trained with.
#[derive(Debug)]
pub struct GreedyAgent {
    /// The configuration saved with the checkpoint.
    pub cfg: RunConfig,
    net: Inference,
    actions: &'static [Action],
    /// Where it came from, for the report.
    pub source: CheckpointInfo,
}

/// Where a checkpoint was found and how far its training had got.
#[derive(Debug, Clone, Serialize)]
pub struct CheckpointInfo {
    /// The online weights file read.
    pub weights: PathBuf,
    /// The run directory, if the checkpoint sits in one.
    pub run_dir: Option<PathBuf>,
    pub learner_step: Option<u64>,
    pub env_steps: Option<u64>,
    pub episodes: Option<u64>,
}

/// Loads a checkpoint given as a run directory, a checkpoint directory or its weights file. The
/// files the checkpoint's manifest lists are checked against it.
pub fn load_checkpoint(path: &Path) -> Result<GreedyAgent> {
    let dir = checkpoint_dir(path)?;
    let weights = if path.is_file() { path.to_owned() } else { dir.join(learner::checkpoint::ONLINE) };
    let config_path = dir.join(learner::checkpoint::CONFIG);
    let read = |p: &Path| std::fs::read(p).with_context(|| format!("reading checkpoint file {}", p.display()));
    let bytes = read(&weights)?;
    let config_bytes = read(&config_path)?;
    verify_against_manifest(&dir, &[(&weights, &bytes), (&config_path, &config_bytes)])?;
    let text = String::from_utf8(config_bytes).with_context(|| format!("checkpoint file {} is not UTF-8 text", config_path.display()))?;
    let cfg = RunConfig::from_toml(&text, &config_path.display().to_string())?;
    let shape = learner::serve::net_shape(&cfg);
    let mut net = Inference::new(shape, cfg.agent.seed, learner::fastnet::default_threads())?;
    net.load(&bytes).with_context(|| {
        format!(
            "checkpoint weights {} do not fit the network its {} describes ({}x{}x{} input, {} scalars, {} actions)",
            weights.display(),
            config_path.display(),
            shape.width,
            shape.height,
            shape.channels,
            shape.scalars,
            shape.actions
        )
    })?;
    let counters = std::fs::read(dir.join(learner::checkpoint::STATE))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .map(|v| v["counters"].clone())
        .unwrap_or_default();
    let run_dir = dir
        .file_name()
        .filter(|n| *n == learner::checkpoint::DIR || *n == learner::checkpoint::OLD_DIR)
        .and_then(|_| dir.parent())
        .map(Path::to_owned);
    let source = CheckpointInfo {
        weights,
        run_dir,
        learner_step: counters["learner_step"].as_u64(),
        env_steps: counters["env_steps"].as_u64(),
        episodes: counters["episodes"].as_u64(),
    };
    let actions = cfg.agent.action_set.actions();
    Ok(GreedyAgent { cfg, net, actions, source })
}

/// The greedy actions (indices into the action set) of `agent` for each environment: the one
/// inference call of evaluation (one batched forward pass of the Q-network, the actors' fast
/// path; the first of equal Q values).
fn greedy_actions(agent: &mut GreedyAgent, envs: &[&Env]) -> Vec<u32> {
    let scalars: Vec<f32> =
        envs.iter().flat_map(|e| learner::train::scalar_features(&agent.cfg, &learner::train::env_scalars(e))).collect();
    agent.net.greedy(envs.iter().map(|e| e.image().data.as_slice()), &scalars)
}

/// The greedy action of `agent` in `env`.
pub fn greedy_action(agent: &mut GreedyAgent, env: &Env) -> Action {
    agent.actions[greedy_actions(agent, &[env])[0] as usize]
}

/// The checkpoint directory `path` names (see [`load_checkpoint`]), with an error that says what
/// a checkpoint is when it is none.
fn checkpoint_dir(path: &Path) -> Result<PathBuf> {
    let what = "expected a run directory of `actor train` or `learner serve`, its checkpoint/ directory, or the online.safetensors in it";
    if !path.exists() {
        bail!("checkpoint {}: no such file or directory ({what})", path.display());
    }
    if path.is_file() {
        if path.extension().is_none_or(|e| e != "safetensors") {
            bail!("{} is not a checkpoint: {what}", path.display());
        }
        let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dir.join(learner::checkpoint::CONFIG).is_file() {
            bail!(
                "{} is not part of a checkpoint: {} is missing beside it (the checkpoint directory holds online.safetensors, config.toml and manifest.json)",
                path.display(),
                dir.join(learner::checkpoint::CONFIG).display()
            );
        }
        return Ok(dir.to_owned());
    }
    let has_weights = |d: &Path| d.join(learner::checkpoint::ONLINE).is_file();
    if has_weights(path) {
        return Ok(path.to_owned());
    }
    for sub in [learner::checkpoint::DIR, learner::checkpoint::OLD_DIR] {
        let d = path.join(sub);
        if has_weights(&d) {
            if sub == learner::checkpoint::OLD_DIR {
                tracing::warn!("{} has only {} (an interrupted save): evaluating it", path.display(), d.display());
            }
            return Ok(d);
        }
    }
    bail!("{} is not a checkpoint: it holds neither online.safetensors nor checkpoint/online.safetensors ({what})", path.display())
}

/// Checks files against the manifest of `dir`, if it has one and lists them.
fn verify_against_manifest(dir: &Path, files: &[(&Path, &[u8])]) -> Result<()> {
    let manifest_path = dir.join(learner::checkpoint::MANIFEST);
    let Ok(text) = std::fs::read(&manifest_path) else { return Ok(()) };
    let manifest: serde_json::Value =
        serde_json::from_slice(&text).with_context(|| format!("checkpoint manifest {} is not JSON", manifest_path.display()))?;
    let entries = manifest["files"].as_array().cloned().unwrap_or_default();
    for (path, bytes) in files {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let Some(entry) = entries.iter().find(|e| e["name"] == name) else { continue };
        let expected = (entry["bytes"].as_u64(), entry["fnv1a64"].as_str().and_then(|h| u64::from_str_radix(h, 16).ok()));
        let found = (Some(bytes.len() as u64), Some(learner::checkpoint::fnv1a64(bytes)));
        if expected != found {
            bail!(
                "checkpoint file {} does not match {} (length or checksum): the checkpoint is corrupt, or was replaced while being read — try again",
                path.display(),
                manifest_path.display()
            );
        }
    }
    Ok(())
}

/// The name of a checkpoint in the table: its run directory's name.
fn default_name(agent: &GreedyAgent, path: &Path) -> String {
    let named = agent.source.run_dir.as_deref().unwrap_or(path);
    let canonical = named.canonicalize().unwrap_or_else(|_| named.to_owned());
    canonical.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// The environment every agent is evaluated in: the `paper` preset's, scored with the paper's
/// reward (hybrid variant), with the agent's camera.
fn eval_env_config(camera: Option<CameraConfig>, traffic: Option<usize>) -> EnvConfig {
    let mut env = RunConfig::preset("paper").expect("the paper preset exists").env;
    env.variant = Variant::Hybrid;
    env.camera = camera;
    if let Some(n) = traffic {
        env.traffic.vehicles = n;
    }
    env
}

/// Outcomes of one agent on one route.
#[derive(Debug, Clone, Serialize)]
pub struct RouteResult {
    pub route: &'static str,
    pub runs: u32,
    pub mean_return: f64,
    pub min_return: f64,
    pub max_return: f64,
    pub completed: u32,
    pub completion_rate: f64,
    pub collisions: u32,
    pub collision_rate: f64,
    /// What was hit, one entry per collision.
    pub collision_kinds: Vec<&'static str>,
    /// Mean over runs of the mean distance to the closest waypoint, metres.
    pub mean_d: f64,
    /// Mean over runs of the mean speed, km/h.
    pub mean_speed_kmh: f64,
    pub mean_steps: f64,
    /// The paper's Table I (Hybrid-DQN, human average), for reference.
    pub paper_hybrid_dqn: Option<f32>,
    pub paper_human: Option<f32>,
}

/// One agent's evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct AgentReport {
    pub name: String,
    /// `model_based` or `checkpoint`.
    pub kind: &'static str,
    /// `hybrid` or `end_to_end` for checkpoints.
    pub variant: Option<Variant>,
    pub checkpoint: Option<CheckpointInfo>,
    /// The camera the agent drives from, e.g. `84x84 gray`.
    pub camera: Option<String>,
    pub epsilon: f32,
    pub seed: u64,
    pub traffic_vehicles: usize,
    /// Mean of the routes' mean returns.
    pub mean_return: f64,
    /// Routes completed in more than half of their runs.
    pub routes_completed_majority: usize,
    pub routes: Vec<RouteResult>,
}

/// The whole evaluation: `{"agents":[...]}`.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub agents: Vec<AgentReport>,
}

/// What to evaluate and how.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    pub routes: Vec<(&'static str, Scenario)>,
    pub runs: u32,
    pub seed: u64,
    pub traffic: Option<usize>,
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
    let town = load_town(None)?;
    let total = agents.len() * opts.routes.len();
    let started = Instant::now();
    let mut done = 0usize;
    let mut reports = Vec::new();
    for agent in agents.iter_mut() {
        let camera = match &agent.driver {
            Driver::ModelBased(_) => None,
            Driver::Greedy(g) => g.cfg.env.camera.clone(),
        };
        let cfg = eval_env_config(camera.clone(), opts.traffic);
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
            camera: camera.map(|c| format!("{}x{} {}", c.width, c.height, if c.rgb { "rgb" } else { "gray" })),
            epsilon: EPSILON,
            seed: opts.seed,
            traffic_vehicles,
            mean_return,
            routes_completed_majority,
            routes,
        });
    }
    Ok(Report { agents: reports })
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
        let actions: Vec<Action> = match driver {
            Driver::ModelBased(policy) => live.iter().map(|&k| policy.act(&envs[k])).collect(),
            Driver::Greedy(agent) => {
                let refs: Vec<&Env> = live.iter().map(|&k| &envs[k]).collect();
                greedy_actions(agent, &refs).into_iter().map(|a| agent.actions[a as usize]).collect()
            }
        };
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
    }
}

/// `actor eval`.
pub fn run(args: &EvalArgs) -> Result<()> {
    if args.name.len() > args.checkpoint.len() {
        bail!("{} --name given for {} --checkpoint: give at most one name per checkpoint", args.name.len(), args.checkpoint.len());
    }
    let mut routes = Vec::new();
    for name in args.route.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        routes.extend(parse_routes(name)?);
    }
    if routes.is_empty() {
        bail!("--route `{}` names no route", args.route);
    }
    let mut agents = vec![model_based()];
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
    let opts = EvalOptions { routes, runs: args.runs, seed: args.seed, traffic: args.traffic, progress: true };
    eprintln!(
        "evaluating {} agent(s) on {} route(s) × {} run(s) (seeds {}..={}), greedy (ε = {EPSILON})",
        agents.len(),
        opts.routes.len(),
        opts.runs,
        opts.seed,
        opts.seed + u64::from(opts.runs.max(1) - 1)
    );
    let report = evaluate(&mut agents, &opts)?;
    let json = serde_json::to_string(&report)?;
    if let Some(path) = &args.json_out {
        write_atomically(path, json.as_bytes())?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{}", table(&report, args.markdown));
    }
    Ok(())
}

/// Writes through a temporary file and a rename, so that an interrupted run leaves no half file.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension(format!("tmp-{}", std::process::id()));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))
}

/// The readable table (or Markdown): one block per route, one row per agent, the paper's Table I
/// beside it; then the agents over all routes.
#[must_use]
pub fn table(report: &Report, markdown: bool) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let Some(first) = report.agents.first() else { return out };
    let header = [
        "route",
        "agent",
        "mean return",
        "completed",
        "collisions",
        "mean d (m)",
        "speed (km/h)",
        "steps",
        "paper Hybrid-DQN",
        "paper human",
    ];
    let mut rows: Vec<[String; 10]> = Vec::new();
    let opt = |x: Option<f32>| x.map_or_else(|| "—".to_owned(), |v| format!("{v:.1}"));
    for (i, r0) in first.routes.iter().enumerate() {
        for (j, a) in report.agents.iter().enumerate() {
            let r = &a.routes[i];
            let first_row = j == 0 || markdown;
            rows.push([
                if first_row { r0.route.to_owned() } else { String::new() },
                a.name.clone(),
                format!("{:.1}", r.mean_return),
                format!("{}/{}", r.completed, r.runs),
                format!("{}/{}", r.collisions, r.runs),
                format!("{:.2}", r.mean_d),
                format!("{:.1}", r.mean_speed_kmh),
                format!("{:.0}", r.mean_steps),
                if first_row { opt(r.paper_hybrid_dqn) } else { String::new() },
                if first_row { opt(r.paper_human) } else { String::new() },
            ]);
        }
    }
    let paper_mean = |f: fn(&RouteResult) -> Option<f32>| -> Option<f32> {
        let v: Option<Vec<f32>> = first.routes.iter().map(f).collect();
        v.filter(|v| !v.is_empty()).map(|v| v.iter().sum::<f32>() / v.len() as f32)
    };
    for (j, a) in report.agents.iter().enumerate() {
        let first_row = j == 0 || markdown;
        let runs: u32 = a.routes.iter().map(|r| r.runs).sum();
        rows.push([
            if first_row { "mean of the routes".to_owned() } else { String::new() },
            a.name.clone(),
            format!("{:.1}", a.mean_return),
            format!("{}/{}", a.routes.iter().map(|r| r.completed).sum::<u32>(), runs),
            format!("{}/{}", a.routes.iter().map(|r| r.collisions).sum::<u32>(), runs),
            format!("{:.2}", a.routes.iter().map(|r| r.mean_d).sum::<f64>() / a.routes.len().max(1) as f64),
            format!("{:.1}", a.routes.iter().map(|r| r.mean_speed_kmh).sum::<f64>() / a.routes.len().max(1) as f64),
            format!("{:.0}", a.routes.iter().map(|r| r.mean_steps).sum::<f64>() / a.routes.len().max(1) as f64),
            if first_row { opt(paper_mean(|r| r.paper_hybrid_dqn)) } else { String::new() },
            if first_row { opt(paper_mean(|r| r.paper_human)) } else { String::new() },
        ]);
    }
    if markdown {
        let _ = writeln!(out, "| {} |", header.join(" | "));
        let _ = writeln!(out, "|{}", ["---|", "---|", "---:|", "---:|", "---:|", "---:|", "---:|", "---:|", "---:|", "---:|"].concat());
        for r in &rows {
            let _ = writeln!(out, "| {} |", r.join(" | "));
        }
    } else {
        let widths: Vec<usize> = (0..header.len())
            .map(|c| rows.iter().map(|r| r[c].chars().count()).chain([header[c].chars().count()]).max().unwrap_or(0))
            .collect();
        let line = |cells: &[String]| -> String {
            let parts: Vec<String> = cells
                .iter()
                .enumerate()
                .map(|(c, s)| if c < 2 { format!("{s:<w$}", w = widths[c]) } else { format!("{s:>w$}", w = widths[c]) })
                .collect();
            parts.join("  ").trim_end().to_owned()
        };
        let _ = writeln!(out, "{}", line(&header.map(str::to_owned)));
        for r in &rows {
            let _ = writeln!(out, "{}", line(r));
        }
    }
    let _ = writeln!(out);
    for a in &report.agents {
        let what = match (&a.kind, &a.checkpoint) {
            (_, Some(c)) => format!(
                "{} agent, {} camera, checkpoint {} (learner step {}, {} env steps, {} episodes)",
                a.variant.map_or("?", |v| match v {
                    Variant::Hybrid => "hybrid",
                    Variant::EndToEnd => "end-to-end",
                }),
                a.camera.as_deref().unwrap_or("no"),
                c.weights.display(),
                c.learner_step.map_or("?".into(), |x| x.to_string()),
                c.env_steps.map_or("?".into(), |x| x.to_string()),
                c.episodes.map_or("?".into(), |x| x.to_string()),
            ),
            _ => "A* planner + pure pursuit + speed control (`actor drive --policy expert`)".to_owned(),
        };
        let routes = a.routes.len();
        let _ = writeln!(
            out,
            "{}{}: {what}; routes completed in most runs: {}/{routes}",
            if markdown { "- " } else { "" },
            a.name,
            a.routes_completed_majority
        );
    }
    let _ = writeln!(
        out,
        "{}greedy (ε = {EPSILON}), {} run(s) per route with seeds {}.., {} traffic cars; every agent scored with the paper's reward (r_w included). Paper columns: Table I of Yurtsever et al. 2020 (CARLA, human drivers).",
        if markdown { "\n" } else { "" },
        first.routes.first().map_or(0, |r| r.runs),
        first.seed,
        first.traffic_vehicles
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_core::scenario::EvalRoute;

    /// A run configuration with a tiny camera and network, so that tests run fast.
    fn tiny_config(variant: Variant) -> RunConfig {
        let mut cfg = RunConfig::preset(if variant == Variant::Hybrid { "paper" } else { "end-to-end" }).unwrap();
        cfg.env.camera = Some(CameraConfig { width: 16, height: 16, ..CameraConfig::default() });
        cfg.agent.conv_filters = 4;
        cfg.agent.hidden = 8;
        cfg
    }

    /// A freshly initialised checkpoint as the learner lays it out (`learner/src/checkpoint.rs`):
    /// online weights, config, state and a manifest of lengths and FNV-1a hashes. Written here
    /// rather than through the learner's agent, so that this test depends only on the format.
    fn write_checkpoint(run_dir: &Path, cfg: &RunConfig) -> PathBuf {
        use learner::checkpoint::{CONFIG, DIR, MANIFEST, ONLINE, STATE, fnv1a64};
        let dir = run_dir.join(DIR);
        std::fs::create_dir_all(&dir).unwrap();
        let vars = learner::net::init_parameters(&learner::serve::net_shape(cfg), 1, &candle_core::Device::Cpu).unwrap();
        let state = serde_json::json!({"version": 1, "counters": {"learner_step": 7, "env_steps": 1234, "episodes": 9}});
        let files = [
            (ONLINE, learner::net::to_safetensors(&vars).unwrap()),
            (CONFIG, cfg.to_toml().into_bytes()),
            (STATE, serde_json::to_vec(&state).unwrap()),
        ];
        let mut entries = Vec::new();
        for (name, bytes) in &files {
            std::fs::write(dir.join(name), bytes).unwrap();
            entries.push(serde_json::json!({"name": name, "bytes": bytes.len(), "fnv1a64": format!("{:016x}", fnv1a64(bytes))}));
        }
        std::fs::write(dir.join(MANIFEST), serde_json::json!({"version": 1, "files": entries}).to_string()).unwrap();
        dir
    }

    fn opts(routes: &[EvalRoute], runs: u32) -> EvalOptions {
        EvalOptions {
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
    fn evaluation_is_deterministic_and_does_not_depend_on_batching() {
        let dir = tempfile::tempdir().unwrap();
        write_checkpoint(dir.path(), &tiny_config(Variant::EndToEnd));
        let weights = dir.path().join("checkpoint").join("online.safetensors");
        let run = |runs: u32| {
            let agent = load_checkpoint(&weights).unwrap();
            assert_eq!(learner::serve::net_shape(&agent.cfg).scalars, 1, "end-to-end: speed only");
            let mut agents = vec![Agent { name: "e2e".into(), driver: Driver::Greedy(Box::new(agent)) }];
            evaluate(&mut agents, &opts(&[EvalRoute::StraightUrban], runs)).unwrap().agents.remove(0).routes.remove(0)
        };
        let (one, two) = (run(1), run(2));
        // Run 0 of a batch of two is the lone run of a batch of one: rows of a batch are
        // independent and each run's traffic comes from its own seed.
        assert_eq!(one.min_return.to_bits(), one.max_return.to_bits());
        assert!(two.min_return.to_bits() == one.mean_return.to_bits() || two.max_return.to_bits() == one.mean_return.to_bits());
        assert_eq!(run(1).mean_return.to_bits(), one.mean_return.to_bits());
    }

    #[test]
    fn a_hybrid_checkpoint_with_path_features_sees_them() {
        let dir = tempfile::tempdir().unwrap();
        let mut cfg = tiny_config(Variant::Hybrid);
        cfg.agent.path_features = true;
        write_checkpoint(dir.path(), &cfg);
        let agent = load_checkpoint(dir.path()).unwrap();
        assert_eq!(learner::serve::net_shape(&agent.cfg).scalars, 5, "speed, d and three path features");
        let mut agents = vec![Agent { name: "hybrid".into(), driver: Driver::Greedy(Box::new(agent)) }];
        let row = evaluate(&mut agents, &opts(&[EvalRoute::RightTurn], 1)).unwrap().agents.remove(0).routes.remove(0);
        assert!(row.mean_return.is_finite() && row.mean_steps > 0.0, "{row:?}");
    }

    #[test]
    fn what_is_not_a_checkpoint_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_checkpoint(dir.path()).unwrap_err().to_string();
        assert!(e.contains(&dir.path().display().to_string()) && e.contains("is not a checkpoint"), "{e}");
        let missing = dir.path().join("nope");
        let e = load_checkpoint(&missing).unwrap_err().to_string();
        assert!(e.contains("no such file") && e.contains("nope"), "{e}");
        let stray = dir.path().join("w.safetensors");
        std::fs::write(&stray, b"x").unwrap();
        let e = load_checkpoint(&stray).unwrap_err().to_string();
        assert!(e.contains("config.toml is missing"), "{e}");
        let text = dir.path().join("notes.txt");
        std::fs::write(&text, b"x").unwrap();
        assert!(load_checkpoint(&text).unwrap_err().to_string().contains("is not a checkpoint"));
    }

    #[test]
    fn corrupt_or_mismatched_weights_are_refused_with_the_file_named() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = tiny_config(Variant::Hybrid);
        let ckpt = write_checkpoint(dir.path(), &cfg);
        let weights = ckpt.join("online.safetensors");
        let mut bytes = std::fs::read(&weights).unwrap();
        let last = bytes.len() - 1;
        bytes[last] ^= 1;
        std::fs::write(&weights, &bytes).unwrap();
        let e = format!("{:#}", load_checkpoint(dir.path()).unwrap_err());
        assert!(e.contains("online.safetensors") && e.contains("checksum"), "{e}");
        // A config that describes another network than the weights (no manifest to catch it).
        std::fs::remove_file(ckpt.join("manifest.json")).unwrap();
        bytes[last] ^= 1;
        std::fs::write(&weights, &bytes).unwrap();
        let mut other = cfg.clone();
        other.agent.hidden = 9;
        std::fs::write(ckpt.join("config.toml"), other.to_toml()).unwrap();
        let e = format!("{:#}", load_checkpoint(&weights).unwrap_err());
        assert!(e.contains("do not fit the network") && e.contains("has shape"), "{e}");
    }
}
