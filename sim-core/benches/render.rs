//! Criterion benches of the front camera at 84×84 and 160×120 (gray and RGB) in the default town
//! with 50 traffic cars, from a fixed pose on the straight urban route.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use sim_core::camera::{Camera, CameraConfig, Image, SceneBox, car_box};
use sim_core::config::EnvConfig;
use sim_core::env::Env;
use sim_core::scenario::{EvalRoute, Scenario};
use sim_core::town::Town;

fn render(c: &mut Criterion) {
    let town = Town::default_town();
    let mut cfg = EnvConfig::default();
    cfg.traffic.vehicles = 50;
    cfg.camera = None;
    let mut env = Env::new(town.clone(), cfg).expect("valid config");
    env.reset(1, Scenario::Eval(EvalRoute::StraightUrban)).expect("route exists");
    let vehicles: Vec<SceneBox> = env.traffic.bodies().enumerate().map(|(i, (b, _))| car_box(b, i)).collect();
    let mut group = c.benchmark_group("front_camera");
    for (w, h, rgb) in [(84, 84, false), (84, 84, true), (160, 120, false), (160, 120, true)] {
        let mut camera = Camera::new(&CameraConfig { width: w, height: h, rgb, ..CameraConfig::default() }).expect("valid camera");
        let mut img = Image::new(w, h, 1);
        let name = format!("{w}x{h}{}", if rgb { "_rgb" } else { "_gray" });
        group.bench_with_input(BenchmarkId::from_parameter(name), &(), |b, ()| {
            b.iter(|| {
                camera.render(&town, env.ego.pos, env.ego.heading, &vehicles, &mut img);
                black_box(&img);
            });
        });
    }
    group.finish();
}

criterion_group!(benches, render);
criterion_main!(benches);
