use sim_core::{collision::overlapping_pairs, config::EnvConfig, env::Env, expert::Expert, scenario::Scenario, town::Town};
fn main() {
    let n: usize = std::env::args().nth(1).map_or(60, |a| a.parse().unwrap());
    let mut cfg = EnvConfig::default();
    cfg.traffic.vehicles = n;
    cfg.time_limit = 100000;
    let mut env = Env::new(Town::default_town(), cfg).unwrap();
    let ex = Expert::default();
    let mut overl = 0;
    let mut moving = 0.0;
    let mut steps = 0;
    for ep in 0..20u64 {
        env.reset(ep, Scenario::Random).unwrap();
        for _ in 0..5000 {
            let a = if ep % 2 == 0 { sim_core::vehicle::Action::new(0.0, 1.0, 0.0) } else { ex.act(&env) };
            let r = env.step(a).unwrap();
            steps += 1;
            let boxes: Vec<_> = env.traffic.bodies().map(|(b, _)| b).collect();
            let pairs = overlapping_pairs(&boxes);
            if !pairs.is_empty() {
                overl += 1;
                if overl < 5 {
                    println!("ep {ep} step {} overlaps {pairs:?}", env.steps());
                    for &(a, b) in &pairs {
                        println!("  {:?}\n  {:?}", boxes[a], boxes[b]);
                    }
                }
            }
            moving += env.traffic.cars.iter().filter(|c| c.active).map(|c| c.speed).sum::<f32>() / n as f32;
            if r.terminated || r.truncated {
                if r.info.collision.is_some() {
                    println!("ego collision {:?} ep {ep}", r.info.collision);
                }
                break;
            }
        }
    }
    println!("steps {steps} overlap-steps {overl} mean traffic speed {:.2}", moving / steps as f32);
}
