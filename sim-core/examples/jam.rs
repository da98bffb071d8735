use rand::SeedableRng;
use sim_core::{
    collision::{Obb, overlapping_pairs},
    math::Vec2,
    town::Town,
    traffic::{EgoView, IdmParams, Traffic},
    vehicle::VehicleParams,
};
fn main() {
    let n: usize = std::env::args().nth(1).map_or(20, |a| a.parse().unwrap());
    let town = Town::default_town();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut tr = Traffic::empty(&town, IdmParams::default(), VehicleParams::default());
    tr.spawn(&town, n, &[], 0.0, &mut rng);
    let ego = EgoView { body: Obb::new(Vec2::new(-500.0, -500.0), Vec2::new(2.25, 0.95), 0.0), speed: 0.0, hold: None };
    let mut overlaps = 0;
    for t in 0..20000u64 {
        tr.manage_junctions(&town, t, None, None);
        tr.step(&town, &ego, 0.1, &mut rng);
        let boxes: Vec<_> = tr.bodies().map(|(b, _)| b).collect();
        overlaps += overlapping_pairs(&boxes).len();
        if t % 4000 == 0 || t == 19999 {
            let stopped = tr.cars.iter().filter(|c| c.active && c.speed < 0.1).count();
            let inactive = tr.cars.iter().filter(|c| !c.active).count();
            println!(
                "t={t} stopped {stopped} inactive {inactive} mean v {:.2} overlaps {overlaps}",
                tr.cars.iter().map(|c| c.speed).sum::<f32>() / n as f32
            );
        }
    }
}
