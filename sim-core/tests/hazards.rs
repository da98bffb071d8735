//! Hazards end to end: each kind is placed on the route ahead (never inside the ego nor off the
//! route), visible, collidable, scripted as its kind says, and deterministic per seed; hazards off
//! leaves episodes as they were.

use sim_core::collision::CollisionKind;
use sim_core::config::EnvConfig;
use sim_core::env::{Env, StepResult};
use sim_core::expert::Expert;
use sim_core::hazards::{HazardKind, HazardsConfig};
use sim_core::scenario::Scenario;
use sim_core::town::Town;

fn config(kind: HazardKind) -> EnvConfig {
    let mut cfg = EnvConfig { camera: None, hazards: HazardsConfig::only(kind), ..EnvConfig::default() };
    cfg.route_length_min = 120.0;
    cfg.route_length_max = 220.0;
    cfg.time_limit = 500;
    cfg
}

fn drive(env: &mut Env, expert: &Expert) -> Vec<StepResult> {
    let mut out = Vec::new();
    while !env.is_done() {
        out.push(env.step(expert.act(env)).unwrap());
    }
    out
}

#[test]
fn explore() {
    for town in ["default_town", "held_out_town"] {
        for kind in HazardKind::ALL {
            let mut env = Env::new(Town::embedded(town).unwrap(), config(kind)).unwrap();
            let mut line = format!("{town} {:<20}", kind.name());
            for seed in 0..8 {
                env.reset(seed, Scenario::Random).unwrap();
                let Some(h) = env.hazard.clone() else {
                    line += " none";
                    continue;
                };
                let r = drive(&mut env, &Expert::default());
                let last = r.last().unwrap();
                let trig = env.hazard.as_ref().unwrap().triggered;
                line += &format!(
                    " [{:.0}/{:.0} {} {:.2} {}{}]",
                    h.s,
                    env.route.length(),
                    last.info.collision.map_or("-", CollisionKind::name),
                    last.info.progress,
                    last.info.steps,
                    if trig { "T" } else { "" }
                );
            }
            println!("{line}");
        }
    }
}
