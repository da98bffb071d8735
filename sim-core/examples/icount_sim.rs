//! The simulator's instruction-count benchmarks, run under callgrind by `scripts/bench-check.sh`
//! (docs/PERFORMANCE.md, "Instruction counts"). `icount_sim list` names them; `icount_sim run NAME` sets
//! one up and runs its measured work inside [`icount_measured`], the only function callgrind
//! counts (`--collect-atstart=no --toggle-collect=*icount_measured*`), then prints one JSON line:
//! the bench, its iterations and the CPU features this process saw (under valgrind, the ones
//! valgrind emulates, not the host's). `icount_sim time NAME REPEATS` runs the same work natively
//! and prints its median wall time per iteration (to relate counts to time).
//!
//! Everything is single-threaded and seeded, so that a count depends on the code alone.

use std::cell::Cell;
use std::hint::black_box;
use std::time::{Duration, Instant};

use sim_core::camera::{Camera, CameraConfig, Image, SceneBox, car_box};
use sim_core::config::EnvConfig;
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::scenario::{EvalRoute, Scenario};
use sim_core::town::Town;

#[path = "../../benches/icount.rs"]
mod icount;

/// The benches: name, what one iteration is.
const BENCHES: &[(&str, &str)] = &[
    ("env_step_camera_84x84", "one env step, default config (20 cars, 12 parked, 84x84 gray camera)"),
    ("env_step_camera_48x48", "one env step, the tuned presets' 48x48 gray camera"),
    ("env_step_no_camera", "one env step, no camera"),
    ("camera_render_84x84", "one 84x84 gray front-camera frame, 50 cars in view range"),
];

/// Steps per env-step bench: a few episodes' worth, resets outside the counted region.
const STEPS: u64 = 400;
const RENDERS: u64 = 50;

thread_local! {
    /// `time` mode: the measured region's wall time so far (`None` under `run`, so that the clock
    /// adds nothing to a count).
    static TIMED: Cell<Option<Duration>> = const { Cell::new(None) };
}

/// The counted region: callgrind collects only while this function runs.
#[inline(never)]
fn icount_measured(work: &mut dyn FnMut()) {
    match TIMED.get() {
        None => work(),
        Some(so_far) => {
            let start = Instant::now();
            work();
            TIMED.set(Some(so_far + start.elapsed()));
        }
    }
}

fn env_steps(camera: Option<CameraConfig>) -> u64 {
    let cfg = EnvConfig { camera, ..EnvConfig::default() };
    let mut env = Env::new(Town::default_town(), cfg).expect("valid config");
    let expert = Expert::default();
    let mut episode = 1;
    env.reset(episode, Scenario::Random).expect("random route");
    for _ in 0..STEPS {
        if env.is_done() {
            episode += 1;
            env.reset(episode, Scenario::Random).expect("random route");
        }
        let action = expert.act(&env);
        icount_measured(&mut || {
            black_box(env.step(action).expect("episode running"));
        });
    }
    STEPS
}

fn camera_render() -> u64 {
    let town = Town::default_town();
    let mut cfg = EnvConfig::default();
    cfg.traffic.vehicles = 50;
    cfg.camera = None;
    let mut env = Env::new(town.clone(), cfg).expect("valid config");
    env.reset(1, Scenario::Eval(EvalRoute::StraightUrban)).expect("route exists");
    let vehicles: Vec<SceneBox> = env.traffic.bodies().enumerate().map(|(i, (b, _))| car_box(b, i)).collect();
    let mut camera = Camera::new(&CameraConfig::default()).expect("valid camera");
    let mut img = Image::new(84, 84, 1);
    for _ in 0..RENDERS {
        icount_measured(&mut || {
            camera.render(&town, env.ego.pos, env.ego.heading, &vehicles, &mut img);
            black_box(&img);
        });
    }
    RENDERS
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["list"] => icount::list(BENCHES),
        ["run", name] => {
            let iterations = run(name);
            icount::report(name, iterations);
        }
        ["time", name, repeats] => {
            // The same work, timed natively: the median over `repeats` runs of its time per iteration.
            let repeats: usize = repeats.parse().unwrap_or(0).max(1);
            let mut per_iteration: Vec<f64> = (0..repeats)
                .map(|_| {
                    TIMED.set(Some(Duration::ZERO));
                    let iterations = run(name);
                    TIMED.get().expect("set above").as_secs_f64() * 1e9 / iterations as f64
                })
                .collect();
            per_iteration.sort_by(f64::total_cmp);
            println!("{{\"bench\":\"{name}\",\"median_ns_per_iteration\":{:.0}}}", per_iteration[repeats / 2]);
        }
        _ => {
            eprintln!("usage: icount_sim list | icount_sim run NAME | icount_sim time NAME REPEATS");
            std::process::exit(2);
        }
    }
}

/// Runs bench `name`; returns its iterations.
fn run(name: &str) -> u64 {
    match name {
        "env_step_camera_84x84" => env_steps(Some(CameraConfig::default())),
        "env_step_camera_48x48" => env_steps(Some(CameraConfig { width: 48, height: 48, ..CameraConfig::default() })),
        "env_step_no_camera" => env_steps(None),
        "camera_render_84x84" => camera_render(),
        other => {
            let names: Vec<&str> = BENCHES.iter().map(|b| b.0).collect();
            eprintln!("icount_sim: unknown bench `{other}`: expected one of {}", names.join(", "));
            std::process::exit(2);
        }
    }
}
