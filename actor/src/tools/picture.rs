//! `actor picture`: a town seen whole from above and through the front camera, as two PNGs — to
//! check an imported map by eye, and for the pictures in docs/MAP-FORMAT.md.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use sim_core::camera::{BirdsEye, BirdsEyeConfig, CameraConfig, SceneBox, car_box};
use sim_core::config::EnvConfig;
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::math::Vec2;
use sim_core::scenario::Scenario;

use crate::eval::routes::town_by_name_or_file;
use crate::tools::drive::parse_size;
use crate::tools::record::write_png;

#[derive(Debug, Args)]
pub struct PictureArgs {
    /// The town: `default_town`, `held_out_town` or a map file (the text format or OpenDRIVE `.xodr`).
    #[arg(long, value_name = "NAME|FILE", default_value = "default_town")]
    pub map: String,
    /// Directory to write `birdseye.png` (the whole town, the route, the ego and the traffic) and
    /// `camera.png` (the ego's front camera) into.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Side of the bird's-eye picture, pixels (the town is fitted into it).
    #[arg(long, default_value_t = 1024)]
    pub size: u32,
    /// Front-camera size, WIDTHxHEIGHT, in colour.
    #[arg(long, value_name = "WxH", default_value = "320x240", value_parser = parse_size)]
    pub camera: (u32, u32),
    /// Seed of the random route and the traffic.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Steps the model-based driver drives before both pictures are taken.
    #[arg(long, default_value_t = 30)]
    pub steps: u32,
}

pub fn run(args: &PictureArgs) -> Result<()> {
    let town = town_by_name_or_file(&args.map)?;
    let camera = CameraConfig { width: args.camera.0, height: args.camera.1, rgb: true, ..CameraConfig::default() };
    let mut env = Env::new(town.clone(), EnvConfig { camera: Some(camera), ..EnvConfig::default() }).context("creating the environment")?;
    env.reset(args.seed, Scenario::Random).with_context(|| format!("starting a random route on {}", args.map))?;
    let expert = Expert::default();
    for _ in 0..args.steps {
        if env.is_done() {
            break;
        }
        let action = expert.act(&env);
        env.step(action)?;
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let front = args.out.join("camera.png");
    write_png(&front, env.image())?;

    // The surface raster covers the whole town (with its margins): fit it into the picture.
    let surface = &town.map.surface;
    let extent = Vec2::new(surface.width as f32, surface.height as f32) * surface.cell;
    let view = BirdsEye::new(&BirdsEyeConfig { size: args.size, metres_per_pixel: extent.x.max(extent.y) / args.size as f32 })?;
    let cars: Vec<SceneBox> = env.traffic.bodies().enumerate().map(|(i, (body, _))| car_box(body, i)).collect();
    let closest = (0..env.route.waypoints.len())
        .min_by(|&a, &b| env.route.waypoints[a].distance(env.ego.pos).total_cmp(&env.route.waypoints[b].distance(env.ego.pos)));
    let whole = view.render(&town, surface.origin + extent / 2.0, env.ego_body(), &cars, &env.route, closest.unwrap_or(0));
    let above = args.out.join("birdseye.png");
    write_png(&above, &whole)?;
    println!("{} and {} ({}, seed {}, after {} steps)", above.display(), front.display(), town.map.name, args.seed, env.steps());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Width and height from a PNG's IHDR chunk.
    fn png_size(path: &std::path::Path) -> (u32, u32) {
        let bytes = std::fs::read(path).unwrap();
        let word = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
        (word(16), word(20))
    }

    #[test]
    fn writes_the_town_from_above_and_the_camera_frame_at_the_sizes_asked() {
        let dir = tempfile::tempdir().unwrap();
        let args = PictureArgs { map: "held_out_town".into(), out: dir.path().join("pics"), size: 96, camera: (40, 30), seed: 3, steps: 5 };
        run(&args).unwrap();
        assert_eq!(png_size(&args.out.join("birdseye.png")), (96, 96));
        assert_eq!(png_size(&args.out.join("camera.png")), (40, 30));
        let e = run(&PictureArgs { map: "no_such_town".into(), ..args }).unwrap_err().to_string();
        assert!(e.contains("no_such_town"), "{e}");
    }
}
