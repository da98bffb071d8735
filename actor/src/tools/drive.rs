//! `actor drive`: runs a policy over evaluation routes and reports per-route outcomes.

use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;
use sim_core::camera::{BirdsEye, BirdsEyeConfig, CameraConfig};
use sim_core::config::EnvConfig;
use sim_core::env::Env;

use crate::eval::episode::Episode;
use crate::eval::policy::Policy;
use crate::eval::routes::{load_town, parse_routes};
use crate::tools::record::RunRecorder;

#[derive(Debug, Args)]
pub struct DriveArgs {
    /// `expert` (the model-based reference driver), `random`, or a checkpoint (a run directory,
    /// its checkpoint/ directory or its online.safetensors), driven greedily with its own camera.
    #[arg(long, default_value = "expert")]
    pub policy: String,
    /// A route name (straight_highway, straight_urban, straight_under_bridge, slight_curve,
    /// sharp_curve, right_turn, left_turn), `all` of them, or `random` (random training routes,
    /// for any map).
    #[arg(long, default_value = "all")]
    pub route: String,
    /// Runs per route; run k uses seed S + k (different traffic).
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Base seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Moving traffic cars (default: the configuration's, 20).
    #[arg(long)]
    pub traffic: Option<usize>,
    /// A map file, the documented text format or OpenDRIVE `.xodr` (default: the embedded town).
    #[arg(long)]
    pub map: Option<std::path::PathBuf>,
    /// Write each step's front-camera and bird's-eye images as numbered PNGs under
    /// DIR/ROUTE/runK/.
    #[arg(long, value_name = "DIR")]
    pub record: Option<std::path::PathBuf>,
    /// With --record, also write an animated GIF of the front camera per run.
    #[arg(long, requires = "record")]
    pub gif: bool,
    /// Front-camera size for --record, WIDTHxHEIGHT (default 160x120, in colour; a checkpoint
    /// policy records what it sees, its own camera).
    #[arg(long, value_name = "WxH", default_value = "160x120", value_parser = parse_size)]
    pub camera: (u32, u32),
    /// Print one JSON object on the last line of stdout instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Give every run a hazard of this kind (stalled_car, pedestrian_crossing, cut_in,
    /// hard_brake, construction, opposite_overtaker, junction_runner), with `--route random` on
    /// 120–220 m routes of 60 s as `actor eval --suite hazards` drives them.
    #[arg(long, value_name = "KIND")]
    pub hazard: Option<String>,
    /// Read the vector sensor (`[env.vector]`, its defaults) each step; with --record the
    /// bird's-eye view shows what it lists and its rays. A checkpoint trained on it reads it anyway.
    #[arg(long)]
    pub vector: bool,
}

/// The bird's-eye view, with the vector sensor's reading drawn over it when the env has one.
fn birdseye_with_vector(env: &mut Env, view: &BirdsEye) -> sim_core::camera::Image {
    let mut bev = env.birdseye(view);
    if let (Some(reading), Some(vc)) = (env.vector(), &env.cfg.vector) {
        view.draw_vector(&mut bev, env.ego.pos, env.ego.pos, env.ego.heading, reading, vc, env.cfg.variant);
    }
    bev
}

/// Parses `WIDTHxHEIGHT`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once('x').ok_or_else(|| format!("`{s}` is not WIDTHxHEIGHT, e.g. 84x84"))?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("`{v}` in `{s}` is not a whole number of pixels"));
    Ok((parse(w)?, parse(h)?))
}

#[derive(Debug, Serialize)]
struct RouteReport {
    route: &'static str,
    runs: u32,
    completed: u32,
    collisions: u32,
    mean_return: f64,
    mean_steps: f64,
    /// Count per collision kind, for the table.
    #[serde(skip)]
    kinds: Vec<&'static str>,
}

pub fn run(args: &DriveArgs) -> Result<()> {
    let scenarios = parse_routes(&args.route)?;
    if args.runs == 0 {
        anyhow::bail!("--runs must be at least 1");
    }
    let town = load_town(args.map.as_deref())?;
    let mut cfg = EnvConfig::default();
    if let Some(n) = args.traffic {
        cfg.traffic.vehicles = n;
    }
    if let Some(name) = &args.hazard {
        let kind = sim_core::hazards::HazardKind::from_name(name)
            .with_context(|| format!("--hazard `{name}`: expected one of {}", sim_core::hazards::HazardKind::names()))?;
        cfg.hazards = sim_core::hazards::HazardsConfig::only(kind);
        (cfg.route_length_min, cfg.route_length_max, cfg.time_limit) = (120.0, 220.0, 600);
    }
    // Rendering costs time: only when recording, or for a policy that drives from the camera.
    cfg.camera =
        args.record.as_ref().map(|_| CameraConfig { width: args.camera.0, height: args.camera.1, rgb: true, ..CameraConfig::default() });
    let mut checkpoint = match args.policy.as_str() {
        "expert" | "random" => None,
        path => {
            let agent = crate::eval::greedy::load_checkpoint(std::path::Path::new(path))
                .with_context(|| format!("--policy `{path}` is neither `expert`, `random` nor a checkpoint"))?;
            cfg.camera.clone_from(&agent.cfg.env.camera);
            cfg.vector.clone_from(&agent.cfg.env.vector);
            Some(agent)
        }
    };
    if args.vector && cfg.vector.is_none() {
        cfg.vector = Some(sim_core::sensor::VectorConfig::default());
    }
    let birdseye = BirdsEye::new(&BirdsEyeConfig::default())?;
    let mut env = Env::new(town, cfg).context("creating the environment")?;
    let mut reports = Vec::new();
    for (name, scenario) in scenarios {
        let mut rep =
            RouteReport { route: name, runs: args.runs, completed: 0, collisions: 0, mean_return: 0.0, mean_steps: 0.0, kinds: Vec::new() };
        for k in 0..args.runs {
            let seed = args.seed + u64::from(k);
            let mut policy = if checkpoint.is_some() { None } else { Some(Policy::from_name(&args.policy, seed)?) };
            env.reset(seed, scenario).with_context(|| format!("starting route {name}"))?;
            let mut recorder = match &args.record {
                Some(dir) => Some(RunRecorder::new(dir.join(name).join(format!("run{k}")), args.gif)?),
                None => None,
            };
            let mut episode = Episode::default();
            loop {
                if let Some(rec) = recorder.as_mut() {
                    let bev = birdseye_with_vector(&mut env, &birdseye);
                    rec.frame(env.steps(), env.image(), &bev)?;
                }
                let action = match (&mut policy, &mut checkpoint) {
                    (Some(p), _) => p.act(&env),
                    (None, Some(agent)) => crate::eval::greedy::greedy_action(agent, &env),
                    (None, None) => unreachable!("a named policy or a checkpoint"),
                };
                let r = env.step(action)?;
                if episode.record(&r) {
                    if episode.arrived {
                        rep.completed += 1;
                    }
                    if let Some(kind) = episode.collision {
                        rep.collisions += 1;
                        rep.kinds.push(kind.name());
                    }
                    if let Some(rec) = recorder.take() {
                        let bev = birdseye_with_vector(&mut env, &birdseye);
                        let mut rec = rec;
                        rec.frame(env.steps(), env.image(), &bev)?;
                        rec.finish()?;
                    }
                    tracing::debug!(route = name, seed, steps = r.info.steps, ret = episode.ret, arrived = r.info.arrived, collision = ?r.info.collision, progress = r.info.progress, "run finished");
                    break;
                }
            }
            rep.mean_return += episode.ret / f64::from(args.runs);
            rep.mean_steps += f64::from(env.steps()) / f64::from(args.runs);
        }
        reports.push(rep);
    }
    if args.json {
        println!("{}", serde_json::json!({ "routes": reports }));
    } else {
        println!("policy: {}   runs per route: {}   traffic: {} cars", args.policy, args.runs, env.cfg.traffic.vehicles);
        println!("{:<22} {:>9} {:>10} {:>12} {:>10}  collision kinds", "route", "completed", "collisions", "mean return", "mean steps");
        for r in &reports {
            println!(
                "{:<22} {:>5}/{:<3} {:>10} {:>12.1} {:>10.1}  {}",
                r.route,
                r.completed,
                r.runs,
                r.collisions,
                r.mean_return,
                r.mean_steps,
                r.kinds.join(",")
            );
        }
    }
    Ok(())
}
