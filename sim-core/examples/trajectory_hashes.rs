//! One hash per configuration of everything an episode sequence produces — simulator state,
//! camera bytes, rewards and episode ends — under seeded random actions of the paper's six and
//! under the model-based driver. Run it before and after a change that must leave trajectories
//! bit-identical, and compare the lines.
//!
//! `cargo run --release -p sim-core --example trajectory_hashes`

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::actions::ActionSet;
use sim_core::camera::CameraConfig;
use sim_core::config::{EnvConfig, Variant};
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::hash::Fnv1a64;
use sim_core::scenario::Scenario;
use sim_core::town::Town;

const STEPS: u32 = 3000;

fn main() {
    let town = Town::default_town();
    let small = CameraConfig { width: 48, height: 48, ..CameraConfig::default() };
    let mut hazards = EnvConfig { camera: Some(small.clone()), ..EnvConfig::default() };
    hazards.hazards.rate = 0.5;
    let configs = [
        ("defaults (84x84, hybrid)", EnvConfig::default()),
        ("end_to_end, 48x48", EnvConfig { variant: Variant::EndToEnd, camera: Some(small.clone()), ..EnvConfig::default() }),
        ("hazards 0.5, 48x48", hazards),
    ];
    for (name, cfg) in configs {
        for driver in ["random", "expert"] {
            let mut env = Env::new(town.clone(), cfg.clone()).expect("a valid configuration");
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut h = Fnv1a64::default();
            let mut seed = 0;
            env.reset(seed, Scenario::Random).expect("reset");
            for _ in 0..STEPS {
                let action = match driver {
                    "random" => ActionSet::Paper6.actions()[rng.random_range(0..6)],
                    _ => Expert::default().act(&env),
                };
                let r = env.step(action).expect("a running episode");
                h.write(&env.state_hash().to_le_bytes());
                h.write(&r.observation.image.map_or(0, |i| i.hash()).to_le_bytes());
                h.write(&r.reward.to_bits().to_le_bytes());
                h.write(&[u8::from(r.terminated), u8::from(r.truncated)]);
                if r.terminated || r.truncated {
                    seed += 1;
                    env.reset(seed, Scenario::Random).expect("reset");
                }
            }
            println!("{name:<26} {driver:<7} {STEPS} steps, {seed} episodes ended: {:016x}", h.finish());
        }
    }
}
