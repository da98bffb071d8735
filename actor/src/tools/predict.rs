//! `actor predict`: a checkpoint's Q values for one observation, with a summary of the network's
//! inputs — so that a checkpoint loaded elsewhere (PyTorch, NumPy: docs/MODEL.md) can be checked
//! against this program. The observation comes from the simulator (`--route NAME --step K`: the
//! route driven K steps by the model-based reference driver, which does not depend on the
//! checkpoint) or from the user (`--frame FILE.png --speed V --d D`, or `--vector FILE.json` for a
//! checkpoint that sees the vector sensor).

use std::path::{Path, PathBuf};

use agent::features::{RawScalars, push_network_inputs, raw_scalars};
use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::json;
use sim_core::config::Variant;
use sim_core::env::{Env, PATH_FEATURES};
use sim_core::expert::Expert;
use sim_core::scenario::{EvalRoute, Scenario};

use crate::eval::greedy::{GreedyAgent, load_checkpoint, q_values};

#[derive(Debug, Args)]
#[command(group = clap::ArgGroup::new("observation").required(true).args(["route", "frame", "vector"]))]
pub struct PredictArgs {
    /// A checkpoint: a run directory, its checkpoint/ directory, or the online.safetensors in it.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Observe on this evaluation route (e.g. right_turn), driven by the reference driver.
    #[arg(long, value_name = "NAME", requires = "step")]
    pub route: Option<String>,
    /// With --route: the step to observe (0 = the first observation after reset).
    #[arg(long, value_name = "K")]
    pub step: Option<u32>,
    /// With --route: the episode's seed (traffic).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// With --route: also write the camera frame used, as PNG (input for --frame elsewhere).
    #[arg(long, value_name = "FILE.png")]
    pub save_frame: Option<PathBuf>,
    /// Observe this camera frame instead: a PNG of the checkpoint's camera size, 8-bit gray or RGB
    /// as the checkpoint's camera (a checkpoint that sees a stack of frames gets it repeated: a
    /// still scene).
    #[arg(long, value_name = "FILE.png", requires = "speed", conflicts_with_all = ["route", "save_frame"])]
    pub frame: Option<PathBuf>,
    /// With --frame: the ego speed, m/s.
    #[arg(long, value_name = "M_PER_S")]
    pub speed: Option<f32>,
    /// With --frame: d, the distance to the closest waypoint, m (hybrid checkpoints).
    #[arg(long, value_name = "METRES")]
    pub d: Option<f32>,
    /// With --route: also write the vector sensor's reading used, as a JSON array (input for
    /// --vector elsewhere; checkpoints with `[env.vector]`).
    #[arg(long, value_name = "FILE.json")]
    pub save_vector: Option<PathBuf>,
    /// Observe this vector sensor reading instead (checkpoints with `[env.vector]` and no
    /// camera): a JSON array of the checkpoint's `VectorConfig::len` numbers in [-1, 1], in the
    /// layout of docs/MODEL.md.
    #[arg(long, value_name = "FILE.json", conflicts_with_all = ["route", "frame", "save_frame", "save_vector"])]
    pub vector: Option<PathBuf>,
    /// With --frame: the path features (checkpoints with agent.path_features): signed lateral
    /// offset (m), near and far heading angles to the route (rad), comma-separated.
    #[arg(long, value_name = "LAT,NEAR,FAR", value_delimiter = ',', allow_hyphen_values = true)]
    pub path: Option<Vec<f32>>,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// An observation: the image as the camera renders it (`H × W × C` bytes), the raw scalars and
/// the vector sensor's reading (empty without the sensor).
struct Observed {
    image: Vec<u8>,
    raw: RawScalars,
    vector: Vec<f32>,
    source: serde_json::Value,
}

pub fn run(args: &PredictArgs) -> Result<()> {
    let mut agent = load_checkpoint(&args.checkpoint)?;
    let obs = match (&args.route, &args.frame) {
        (Some(route), _) => observe_route(&agent, route, args.step.unwrap_or(0), args.seed, args)?,
        (None, Some(frame)) => observe_frame(&agent, frame, args)?,
        (None, None) => observe_vector(&agent, args.vector.as_deref().expect("clap requires --route, --frame or --vector"))?,
    };
    let mut features = Vec::new();
    push_network_inputs(&agent.cfg, &obs.raw, &obs.vector, &mut features);
    let q = q_values(&mut agent, &obs.image, &features);
    let greedy = agent::fastnet::argmax(&q);
    let shape = agent.cfg.net_shape();
    let n = obs.image.len() as f64;
    let pixels = obs.image.iter().map(|&b| f64::from(b) / 255.0);
    let report = json!({
        "checkpoint": agent.source.weights,
        "variant": agent.cfg.env.variant,
        "path_features": agent.cfg.agent.path_features,
        "observation": obs.source,
        "input": {
            "image": {
                "height": shape.height, "width": shape.width, "channels": shape.channels,
                "scaled_mean": pixels.clone().sum::<f64>() / n,
                "scaled_min": pixels.clone().fold(f64::INFINITY, f64::min),
                "scaled_max": pixels.fold(f64::NEG_INFINITY, f64::max),
            },
            "raw": {
                "speed_mps": obs.raw[0], "d_m": obs.raw[1],
                "lateral_m": obs.raw[2], "near_heading_rad": obs.raw[3], "far_heading_rad": obs.raw[4],
            },
            "vector": agent.cfg.vector_layout().map(|layout| json!({"layout": layout, "values": obs.vector})),
            "scalar_names": scalar_names(&agent),
            "scalars": features,
        },
        "q_values": q,
        "greedy_action": greedy,
        "actions": agent.actions.iter().map(|a| json!({"throttle": a.throttle, "brake": a.brake, "steer": a.steer})).collect::<Vec<_>>(),
    });
    if args.json {
        println!("{report}");
    } else {
        println!("checkpoint {} ({})", agent.source.weights.display(), report["variant"].as_str().unwrap_or_default());
        println!("image {}x{}x{}, scaled mean {:.4}", shape.width, shape.height, shape.channels, report["input"]["image"]["scaled_mean"]);
        println!(
            "scalars {}",
            scalar_names(&agent).iter().zip(&features).map(|(n, v)| format!("{n} = {v:.6}")).collect::<Vec<_>>().join(", ")
        );
        for (i, (qi, a)) in q.iter().zip(agent.actions).enumerate() {
            let mark = if i == greedy { "  <- greedy" } else { "" };
            println!("action {i} (throttle {:.2}, brake {:.2}, steer {:+.2}): Q = {qi:.6}{mark}", a.throttle, a.brake, a.steer);
        }
    }
    Ok(())
}

/// The names of the network's inputs besides the image, in order
/// (`agent::features::push_network_inputs`): the vector sensor's as `SEGMENT[ITEM].FIELD`.
fn scalar_names(agent: &GreedyAgent) -> Vec<String> {
    if let Some(v) = &agent.cfg.env.vector {
        return v
            .segments(agent.cfg.env.variant)
            .iter()
            .flat_map(|s| (0..s.count).flat_map(move |i| (0..s.fields).map(move |f| format!("{}[{i}].{f}", s.name))))
            .collect();
    }
    let names: &[&str] = match agent.cfg.env.variant {
        Variant::Hybrid if agent.cfg.agent.path_features => {
            &["speed/v0", "d/d0", "lateral/lane_width", "near_heading_rad", "far_heading_rad"]
        }
        Variant::Hybrid => &["speed/v0", "d/d0"],
        Variant::EndToEnd => &["speed/v0"],
    };
    names.iter().map(|&n| n.to_owned()).collect()
}

/// Resets route `name` with `seed`, drives `step` steps with the reference driver and observes.
fn observe_route(agent: &GreedyAgent, name: &str, step: u32, seed: u64, args: &PredictArgs) -> Result<Observed> {
    let route = EvalRoute::from_name(name).with_context(|| {
        format!("--route `{name}` is not an evaluation route: expected one of {}", EvalRoute::ALL.map(EvalRoute::name).join(", "))
    })?;
    let mut env = Env::new(sim_core::town::Town::default_town(), agent.cfg.env.clone()).context("creating the environment")?;
    env.reset(seed, Scenario::Eval(route)).with_context(|| format!("starting route {name}"))?;
    let driver = Expert::default();
    for k in 0..step {
        let action = driver.act(&env);
        let r = env.step(action)?;
        if r.terminated || r.truncated {
            bail!("--step {step}: the episode on {name} (seed {seed}) ended after {} steps; choose a step below {}", k + 1, k + 1);
        }
    }
    if let Some(path) = &args.save_frame {
        anyhow::ensure!(agent.cfg.env.camera.is_some(), "--save-frame: the checkpoint has no camera");
        crate::tools::record::write_png(path, env.image())?;
    }
    let vector = env.vector().map(<[f32]>::to_vec).unwrap_or_default();
    if let Some(path) = &args.save_vector {
        anyhow::ensure!(agent.cfg.env.vector.is_some(), "--save-vector: the checkpoint has no vector sensor ([env.vector])");
        std::fs::write(path, serde_json::to_string(&vector)?).with_context(|| format!("--save-vector: writing {}", path.display()))?;
    }
    Ok(Observed {
        image: env.stacked_image().data.clone(),
        raw: agent::features::env_scalars(&env),
        vector,
        source: json!({"route": name, "step": step, "seed": seed, "frame": args.save_frame, "vector": args.save_vector}),
    })
}

/// Reads a frame and the scalars the user gave.
fn observe_frame(agent: &GreedyAgent, path: &Path, args: &PredictArgs) -> Result<Observed> {
    let shape = agent.cfg.net_shape();
    let camera = agent.cfg.env.camera.as_ref().context("the checkpoint has no camera")?;
    let (frame_channels, stack) = (usize::from(camera.channels()), camera.stack as usize);
    let image = read_png(path)?;
    let (w, h, c) = (image.0, image.1, image.2);
    if (w, h, c) != (shape.width, shape.height, frame_channels) {
        bail!(
            "--frame {}: {w}x{h} with {c} channel(s), but the checkpoint's camera is {}x{} {} — give a frame of that size",
            path.display(),
            shape.width,
            shape.height,
            if frame_channels == 1 { "gray (8-bit grayscale PNG)" } else { "RGB (8-bit RGB PNG)" }
        );
    }
    let speed = args.speed.context("--frame needs --speed (m/s)")?;
    let hybrid = agent.cfg.env.variant == Variant::Hybrid;
    let d = match (hybrid, args.d) {
        (true, Some(d)) => d,
        (true, None) => bail!("--d (m) is an input of this hybrid checkpoint: give it with --frame"),
        (false, Some(_)) => bail!("--d: this end-to-end checkpoint does not see d; leave it out"),
        (false, None) => 0.0,
    };
    let path_features = match (hybrid && agent.cfg.agent.path_features, &args.path) {
        (true, Some(p)) => <[f32; PATH_FEATURES]>::try_from(p.as_slice())
            .map_err(|_| anyhow::anyhow!("--path takes {PATH_FEATURES} comma-separated numbers (LAT,NEAR,FAR), not {}", p.len()))?,
        (true, None) => bail!("--path LAT,NEAR,FAR is an input of this checkpoint (agent.path_features): give it with --frame"),
        (false, Some(_)) => bail!("--path: this checkpoint does not see path features (agent.path_features = false); leave it out"),
        (false, None) => [0.0; PATH_FEATURES],
    };
    // A checkpoint that sees a stack of frames gets the one frame as a still scene: repeated.
    let mut stacked = Vec::new();
    sim_core::camera::interleave_frames(&vec![image.3.as_slice(); stack], frame_channels, &mut stacked);
    Ok(Observed {
        image: stacked,
        raw: raw_scalars(speed, d, path_features),
        vector: Vec::new(),
        source: json!({"frame": path, "speed_mps": speed, "d_m": d}),
    })
}

/// Reads a vector sensor reading the user gave (a JSON array), checked against the checkpoint's
/// layout.
fn observe_vector(agent: &GreedyAgent, path: &Path) -> Result<Observed> {
    let cfg = &agent.cfg;
    let layout = cfg.vector_layout().context("--vector: the checkpoint has no vector sensor ([env.vector]); give --frame or --route")?;
    anyhow::ensure!(cfg.env.camera.is_none(), "--vector: the checkpoint also sees a camera; observe it with --route");
    let text = std::fs::read_to_string(path).with_context(|| format!("--vector: reading {}", path.display()))?;
    let vector: Vec<f32> =
        serde_json::from_str(&text).with_context(|| format!("--vector: {} is not a JSON array of numbers", path.display()))?;
    if vector.len() != cfg.vector_len() {
        bail!("--vector {}: {} values, but the checkpoint's layout `{layout}` has {}", path.display(), vector.len(), cfg.vector_len());
    }
    if let Some((k, v)) = vector.iter().enumerate().find(|(_, v)| !v.is_finite() || v.abs() > 1.0) {
        bail!("--vector {}: value {k} is {v}; the vector sensor's values lie in [-1, 1]", path.display());
    }
    Ok(Observed { image: Vec::new(), raw: RawScalars::default(), vector, source: json!({"vector": path}) })
}

/// An 8-bit gray or RGB PNG: width, height, channels and the pixels row by row.
fn read_png(path: &Path) -> Result<(usize, usize, usize, Vec<u8>)> {
    let file = std::fs::File::open(path).with_context(|| format!("--frame: opening {}", path.display()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .with_context(|| format!("--frame: {} is not a PNG", path.display()))?;
    let mut buf = vec![0; reader.output_buffer_size().context("PNG too large")?];
    let info = reader.next_frame(&mut buf).with_context(|| format!("--frame: decoding {}", path.display()))?;
    let channels = match (info.color_type, info.bit_depth) {
        (png::ColorType::Grayscale, png::BitDepth::Eight) => 1,
        (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
        (color, depth) => bail!("--frame {}: {color:?} at {depth:?} bits; expected an 8-bit grayscale or RGB PNG", path.display()),
    };
    buf.truncate(info.buffer_size());
    Ok((info.width as usize, info.height as usize, channels, buf))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{tiny_config, write_checkpoint};

    fn args(checkpoint: &Path, frame: &Path, d: Option<f32>) -> PredictArgs {
        PredictArgs {
            checkpoint: checkpoint.to_path_buf(),
            route: None,
            step: None,
            seed: 0,
            save_frame: None,
            frame: Some(frame.to_path_buf()),
            speed: Some(5.0),
            d,
            save_vector: None,
            vector: None,
            path: None,
            json: true,
        }
    }

    #[test]
    fn frames_and_scalars_that_do_not_fit_the_checkpoint_are_refused_with_what_fits() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = tiny_config(Variant::Hybrid);
        write_checkpoint(dir.path(), &cfg);
        let agent = load_checkpoint(dir.path()).unwrap();
        let shape = cfg.net_shape();
        let frame = dir.path().join("f.png");
        let img = |w: u32, h: u32| sim_core::camera::Image { width: w, height: h, channels: 1, data: vec![7; (w * h) as usize] };
        crate::tools::record::write_png(&frame, &img(shape.width as u32 + 1, shape.height as u32)).unwrap();
        let e = observe_frame(&agent, &frame, &args(dir.path(), &frame, Some(1.0))).err().unwrap().to_string();
        assert!(e.contains("f.png") && e.contains(&format!("camera is {}x{}", shape.width, shape.height)), "{e}");

        crate::tools::record::write_png(&frame, &img(shape.width as u32, shape.height as u32)).unwrap();
        let e = observe_frame(&agent, &frame, &args(dir.path(), &frame, None)).err().unwrap().to_string();
        assert!(e.contains("--d (m) is an input of this hybrid checkpoint"), "{e}");
        let ok = observe_frame(&agent, &frame, &args(dir.path(), &frame, Some(2.0))).unwrap();
        assert_eq!((ok.image.len(), ok.raw[0], ok.raw[1]), (shape.width * shape.height, 5.0, 2.0));

        let mut with_path = args(dir.path(), &frame, Some(2.0));
        with_path.path = Some(vec![0.1, 0.2]);
        let e = observe_frame(&agent, &frame, &with_path).err().unwrap().to_string();
        assert!(e.contains("does not see path features"), "{e}");
    }
}
