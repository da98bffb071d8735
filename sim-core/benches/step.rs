//! Criterion benches of one environment step with 0, 50 and 100 traffic vehicles, driven by the
//! reference driver (its own thinking is outside the timed region).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use sim_core::config::EnvConfig;
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::scenario::Scenario;
use sim_core::town::Town;

fn step(c: &mut Criterion) {
    let town = Town::default_town();
    let mut group = c.benchmark_group("env_step");
    for vehicles in [0usize, 50, 100] {
        let mut cfg = EnvConfig::default();
        cfg.traffic.vehicles = vehicles;
        let mut env = Env::new(town.clone(), cfg).expect("default config is valid");
        let expert = Expert::default();
        let mut episode = 0u64;
        group.bench_with_input(BenchmarkId::from_parameter(vehicles), &vehicles, |b, _| {
            b.iter_custom(|iters| {
                let mut timed = Duration::ZERO;
                for _ in 0..iters {
                    if env.is_done() {
                        episode += 1;
                        env.reset(episode, Scenario::Random).expect("random route");
                    }
                    let action = expert.act(&env);
                    let start = Instant::now();
                    black_box(env.step(action).expect("episode running"));
                    timed += start.elapsed();
                }
                timed
            });
        });
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
