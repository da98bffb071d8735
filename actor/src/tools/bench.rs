//! `actor bench`: simulator throughput on one core.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use sim_core::camera::CameraConfig;
use sim_core::config::EnvConfig;
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::scenario::Scenario;

use crate::eval::routes::load_town;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Environment steps per second on one core (physics, traffic, collisions, reward, and the
    /// camera with --camera or the vector sensor with --observation vector).
    Sim(SimArgs),
}

#[derive(Debug, Args)]
pub struct SimArgs {
    /// Moving traffic cars.
    #[arg(long, default_value_t = 50)]
    pub vehicles: usize,
    /// Render the front camera each step at WIDTHxHEIGHT (gray), e.g. 84x84.
    #[arg(long, value_name = "WxH", value_parser = crate::tools::drive::parse_size)]
    pub camera: Option<(u32, u32)>,
    /// Steps to time.
    #[arg(long, default_value_t = 200_000)]
    pub steps: u64,
    /// A map file, the documented text format or OpenDRIVE `.xodr` (default: the embedded town).
    #[arg(long)]
    pub map: Option<std::path::PathBuf>,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
    /// Give every episode a hazard (all kinds) and time the same steps without hazards too, in
    /// the same run: the report adds both rates and their ratio.
    #[arg(long)]
    pub hazards: bool,
    /// What the environment observes each step: `camera` (the front camera with --camera, none
    /// without), `vector` (the vector sensor, `[env.vector]` defaults, no camera) or `none`.
    #[arg(long, value_enum, default_value_t = Observation::Camera)]
    pub observation: Observation,
}

/// The observation `bench sim` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Observation {
    Camera,
    Vector,
    None,
}

pub fn run(cmd: &BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Sim(args) => sim(args),
    }
}

/// Drives random training episodes with the reference driver (so that episodes last) and times
/// `Env::step` alone; resets and the driver's own thinking are timed apart.
fn sim(args: &SimArgs) -> Result<()> {
    let mut cfg = EnvConfig::default();
    cfg.traffic.vehicles = args.vehicles;
    cfg.camera = args.camera.map(|(width, height)| CameraConfig { width, height, ..CameraConfig::default() });
    if args.observation != Observation::Camera && args.camera.is_some() {
        anyhow::bail!("--camera needs --observation camera");
    }
    if args.observation == Observation::Vector {
        cfg.vector = Some(sim_core::sensor::VectorConfig::default());
    }
    let load = Instant::now();
    let town = load_town(args.map.as_deref())?;
    let map_load_secs = load.elapsed().as_secs_f64();
    let plain = time_steps(&town, cfg.clone(), args.steps)?;
    let hazards = if args.hazards {
        cfg.hazards = sim_core::hazards::HazardsConfig { rate: 1.0, ..Default::default() };
        Some(time_steps(&town, cfg, args.steps)?)
    } else {
        None
    };
    let (steps_per_sec, with_resets, episodes) = hazards.unwrap_or(plain);
    if args.json {
        let mut v = serde_json::json!({
            "steps_per_sec": steps_per_sec.round(),
            "vehicles": args.vehicles,
            "camera": args.camera.map(|(w, h)| format!("{w}x{h}")),
            "observation": format!("{:?}", args.observation).to_lowercase(),
            "map": args.map.as_ref().map(|p| p.display().to_string()),
            "map_load_secs": map_load_secs,
        });
        if hazards.is_some() {
            v["hazards"] = serde_json::json!(true);
            v["steps_per_sec_without_hazards"] = serde_json::json!(plain.0.round());
            v["ratio_to_without_hazards"] = serde_json::json!((steps_per_sec / plain.0 * 1000.0).round() / 1000.0);
        }
        println!("{v}");
    } else {
        println!(
            "vehicles {}{}{}: {:.0} steps/s in Env::step, {:.0} steps/s with resets ({} episodes), map loaded in {:.3} s",
            args.vehicles,
            if hazards.is_some() { ", a hazard per episode" } else { "" },
            if args.observation == Observation::Vector { ", vector sensor" } else { "" },
            steps_per_sec,
            with_resets,
            episodes,
            map_load_secs
        );
        if hazards.is_some() {
            println!("without hazards: {:.0} steps/s in Env::step; ratio {:.3}", plain.0, steps_per_sec / plain.0);
        }
    }
    Ok(())
}

/// Times `total` steps of random episodes on `town` under `cfg`: steps/s in `Env::step`, steps/s
/// with resets, and the episodes driven.
fn time_steps(town: &std::sync::Arc<sim_core::town::Town>, cfg: EnvConfig, total: u64) -> Result<(f64, f64, u64)> {
    let args_steps = total;
    let mut env = Env::new(town.clone(), cfg).context("creating the environment")?;
    let expert = Expert::default();
    let (mut step_time, mut reset_time) = (Duration::ZERO, Duration::ZERO);
    let (mut steps, mut episodes) = (0u64, 0u64);
    let wall = Instant::now();
    let mut last_report = Instant::now();
    while steps < args_steps {
        let action = expert.act(&env);
        let t = Instant::now();
        let r = env.step(action)?;
        step_time += t.elapsed();
        steps += 1;
        if r.terminated || r.truncated {
            episodes += 1;
            let t = Instant::now();
            env.reset(episodes, Scenario::Random)?;
            reset_time += t.elapsed();
        }
        if last_report.elapsed() > Duration::from_secs(2) {
            tracing::info!(steps, "benchmarking");
            last_report = Instant::now();
        }
    }
    let steps_per_sec = steps as f64 / step_time.as_secs_f64();
    let with_resets = steps as f64 / (step_time + reset_time).as_secs_f64();
    tracing::info!(steps_per_sec, with_resets, episodes, wall_s = wall.elapsed().as_secs_f64(), "done");
    Ok((steps_per_sec, with_resets, episodes))
}
