//! The vector sensor (`[env.vector]`): occlusion by parked cars and buildings, the list's order and
//! padding, every value within [−1, 1] on both towns with hazards and traffic, determinism bit for
//! bit, and the layout's length for both variants.

use std::sync::Arc;

use sim_core::collision::Obb;
use sim_core::config::{EnvConfig, Variant};
use sim_core::env::Env;
use sim_core::expert::Expert;
use sim_core::hazards::{Hazard, HazardKind, HazardsConfig, PropKind};
use sim_core::math::Vec2;
use sim_core::scenario::Scenario;
use sim_core::sensor::{OBJECT_FIELDS, Sensor, VectorConfig, World};
use sim_core::town::Town;
use sim_core::traffic::Traffic;
use sim_core::vehicle::{Action, VehicleState};

fn config(variant: Variant) -> EnvConfig {
    EnvConfig { camera: None, vector: Some(VectorConfig::default()), variant, ..EnvConfig::default() }
}

/// The object slots of an end-to-end reading (ego, then objects).
fn objects(reading: &[f32], k: usize) -> Vec<&[f32]> {
    reading[3..3 + k * OBJECT_FIELDS].chunks_exact(OBJECT_FIELDS).collect()
}

/// A pedestrian crossing's hazard (its walker and its parked car), to move by hand.
fn crossing_hazard(town: &Arc<Town>) -> Hazard {
    let cfg = EnvConfig { hazards: HazardsConfig::only(HazardKind::PedestrianCrossing), ..config(Variant::EndToEnd) };
    let mut env = Env::new(town.clone(), cfg).unwrap();
    let h = (0..20)
        .find_map(|seed| {
            env.reset(seed, Scenario::Random).unwrap();
            env.hazard.clone()
        })
        .expect("a crossing placed in some episode");
    assert!(!h.walkers.is_empty() && h.props.iter().any(|p| p.kind == PropKind::ParkedCar));
    h
}

/// Reads the world of an ego at (40, −1.75) heading east on the default town's bottom street,
/// with no traffic, the cars `parked` and the hazard `hazard`.
fn read(town: &Town, parked: &[Obb], hazard: Option<&Hazard>) -> Vec<f32> {
    let cfg = config(Variant::EndToEnd);
    let ego = VehicleState::at_rest(Vec2::new(40.0, -1.75), 0.0);
    let traffic = Traffic::empty(town, cfg.traffic.idm, cfg.vehicle);
    let world = World {
        town,
        vehicle: &cfg.vehicle,
        ego: &ego,
        prev_speed: 0.0,
        dt: cfg.dt,
        traffic: &traffic,
        parked,
        hazard,
        path: None,
        d0: cfg.reward.d0,
    };
    let mut out = Vec::new();
    Sensor::default().read(cfg.vector.as_ref().unwrap(), &world, &mut out);
    assert_eq!(out.len(), cfg.vector.as_ref().unwrap().len(Variant::EndToEnd));
    out
}

fn car(x: f32, y: f32) -> Obb {
    Obb::new(Vec2::new(x, y), Vec2::new(2.25, 0.95), 0.0)
}

/// The kinds (one-hot index) of the listed objects, nearest first.
fn kinds(reading: &[f32]) -> Vec<usize> {
    objects(reading, 8).iter().filter(|o| o[0] == 1.0).map(|o| (9..13).find(|&k| o[k] == 1.0).unwrap() - 9).collect()
}

#[test]
fn a_walker_behind_a_parked_car_is_hidden_until_it_steps_out() {
    let town = Town::default_town();
    let mut h = crossing_hazard(&town);
    // The crossing's parked car 15 m ahead in the ego's lane, its walker 3.5 m behind it.
    let p = h.props.iter_mut().find(|p| p.kind == PropKind::ParkedCar).unwrap();
    p.body = car(55.0, -1.75);
    h.props.retain(|p| p.kind == PropKind::ParkedCar);
    h.walkers.truncate(1);
    h.walkers[0].pos = Vec2::new(58.5, -1.75);
    let hidden = read(&town, &[], Some(&h));
    assert_eq!(kinds(&hidden), vec![1], "only the parked car: {:?}", objects(&hidden, 2));
    // Stepped out to the left of the car, into the open.
    h.walkers[0].pos = Vec2::new(58.5, 2.0);
    let seen = read(&town, &[], Some(&h));
    assert_eq!(kinds(&seen), vec![1, 2], "the parked car, then the walker");
    let w = objects(&seen, 8)[1];
    assert!((w[1] - 18.5 / 50.0).abs() < 1e-5 && (w[2] - 3.75 / 50.0).abs() < 1e-5, "{w:?}");
    // And with the car gone, the walker where it hid is seen too.
    h.walkers[0].pos = Vec2::new(58.5, -1.75);
    h.props.clear();
    assert_eq!(kinds(&read(&town, &[], Some(&h))), vec![2]);
}

#[test]
fn a_building_hides_what_is_behind_it() {
    let town = Town::default_town();
    // The block's building spans x 13–47 and y 13–47; the ego is at (40, −1.75) facing east, the
    // hidden car 43 m away past the building's corner.
    let behind = car(50.0, 40.0);
    let open = car(55.0, 6.0);
    let r = read(&town, &[behind, open], None);
    assert_eq!(kinds(&r), vec![1], "only the car in the open: {:?}", objects(&r, 2));
    let o = objects(&r, 8)[0];
    assert!((o[1] - 15.0 / 50.0).abs() < 1e-5, "{o:?}");
}

#[test]
fn objects_are_listed_nearest_first_and_padded_with_zeros() {
    let town = Town::default_town();
    let parked = [car(70.0, 6.0), car(50.0, 3.0), car(60.0, -6.0), car(200.0, -1.75)];
    let r = read(&town, &parked, None);
    let slots = objects(&r, 8);
    let present: Vec<f32> = slots.iter().map(|o| o[0]).collect();
    assert_eq!(present, [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0], "the car 160 m away is out of range");
    let xs: Vec<f32> = slots[..3].iter().map(|o| o[1] * 50.0).collect();
    assert!((xs[0] - 10.0).abs() < 1e-4 && (xs[1] - 20.0).abs() < 1e-4 && (xs[2] - 30.0).abs() < 1e-4, "{xs:?}");
    for o in &slots[..3] {
        // Parked, at rest: velocity 0 relative to the ego at rest; heading along the ego's;
        // 4.5 × 1.9 m.
        assert_eq!(&o[3..7], &[0.0, 0.0, 1.0, 0.0]);
        assert!((o[7] - 0.45).abs() < 1e-6 && (o[8] - 0.38).abs() < 1e-6);
        assert_eq!(&o[9..], &[0.0, 1.0, 0.0, 0.0]);
    }
    assert!(slots[3..].iter().all(|o| o.iter().all(|&v| v == 0.0)));
}

/// Drives `steps` steps of random episodes with hazards and 50 cars (the reference driver, with
/// a random action now and then), checking every reading, and returns them all.
fn drive(town: &Arc<Town>, variant: Variant, seed: u64, steps: usize) -> Vec<Vec<f32>> {
    let mut cfg = config(variant);
    cfg.traffic.vehicles = 50;
    cfg.hazards = HazardsConfig { rate: 1.0, ..HazardsConfig::default() };
    let vc = cfg.vector.clone().unwrap();
    let k = vc.objects as usize;
    let mut env = Env::new(town.clone(), cfg).unwrap();
    let expert = Expert::default();
    let mut episode = seed;
    env.reset(episode, Scenario::Random).unwrap();
    let mut out = vec![env.vector().unwrap().to_vec()];
    for i in 0..steps {
        let action = if i % 7 == 3 { Action::new(1.0, 0.0, if i % 2 == 0 { 1.0 } else { -1.0 }) } else { expert.act(&env) };
        let r = env.step(action).unwrap();
        let v = r.observation.vector.expect("the vector sensor is configured");
        assert_eq!(v.len(), vc.len(variant));
        assert!(v.iter().all(|x| (-1.0..=1.0).contains(x)), "{variant:?} step {i}: a value outside [-1, 1]: {v:?}");
        let off = v.len() - k * OBJECT_FIELDS - 2 * vc.rays as usize;
        let slots: Vec<&[f32]> = v[off..off + k * OBJECT_FIELDS].chunks_exact(OBJECT_FIELDS).collect();
        let n = slots.iter().take_while(|o| o[0] == 1.0).count();
        assert!(slots[n..].iter().all(|o| o.iter().all(|&x| x == 0.0)), "absent slots are all zero");
        assert!(slots[..n].iter().all(|o| o[9..].iter().sum::<f32>() == 1.0), "one kind each");
        let dist: Vec<f32> = slots[..n].iter().map(|o| o[1].hypot(o[2])).collect();
        assert!(dist.windows(2).all(|w| w[0] <= w[1] + 1e-6), "nearest first: {dist:?}");
        out.push(v);
        if r.terminated || r.truncated {
            episode += 1;
            env.reset(episode, Scenario::Random).unwrap();
        }
    }
    out
}

#[test]
fn every_value_is_within_bounds_on_both_towns() {
    for town in [Town::default_town(), Town::embedded("held_out_town").unwrap()] {
        for variant in [Variant::Hybrid, Variant::EndToEnd] {
            let readings = drive(&town, variant, 3, 300);
            assert!(readings.iter().any(|v| v.iter().any(|&x| x != 0.0 && x != 1.0)));
        }
    }
}

#[test]
fn same_seed_and_actions_give_identical_readings() {
    let town = Town::default_town();
    let bits = |r: Vec<Vec<f32>>| r.into_iter().map(|v| v.into_iter().map(f32::to_bits).collect::<Vec<_>>()).collect::<Vec<_>>();
    let a = bits(drive(&town, Variant::Hybrid, 11, 250));
    assert_eq!(a, bits(drive(&town, Variant::Hybrid, 11, 250)));
    assert_ne!(a, bits(drive(&town, Variant::Hybrid, 12, 250)));
}

#[test]
fn the_layout_has_the_configured_length() {
    for variant in [Variant::Hybrid, Variant::EndToEnd] {
        let cfg = config(variant);
        let vc = cfg.vector.clone().unwrap();
        let mut env = Env::new(Town::default_town(), cfg).unwrap();
        assert_eq!(env.vector().unwrap().len(), vc.len(variant));
        let r = env.step(Action::new(1.0, 0.0, 0.0)).unwrap();
        assert_eq!(r.observation.vector.unwrap().len(), vc.len(variant));
        // Speed over the maximum; acceleration from rest over the larger of the limits.
        let v = env.vector().unwrap();
        assert!(v[0] > 0.0 && v[2] > 0.0, "{:?}", &v[..3]);
    }
    assert_eq!(VectorConfig::default().len(Variant::Hybrid), 3 + 4 + 10 + 8 * 13 + 16 * 2);
    let no_vector = Env::new(Town::default_town(), EnvConfig { camera: None, ..EnvConfig::default() }).unwrap();
    assert!(no_vector.vector().is_none());
}

#[test]
fn a_ray_reads_a_parked_car_straight_ahead() {
    let town = Town::default_town();
    // Its rear 12.75 m ahead of the ego's centre: ray 0 (ahead) stops there.
    let r = read(&town, &[car(55.0, -1.75)], None);
    let rays = &r[r.len() - 32..];
    assert!((rays[0] * 50.0 - 12.75).abs() < 1e-3, "{:?}", &rays[..4]);
    // The ray behind passes no car; every obstacle distance is a fraction of the range.
    assert!(rays[16] > rays[0]);
    // Across the street to the left the road's edge is a few metres away (the curb at 6 m).
    let left_edge = rays[2 * 4 + 1] * 50.0;
    assert!(left_edge > 5.0 && left_edge < 12.0, "{left_edge}");
}

#[test]
fn the_birdseye_view_shows_the_reading() {
    use sim_core::camera::{BirdsEye, BirdsEyeConfig};
    let mut cfg = config(Variant::Hybrid);
    cfg.traffic.vehicles = 50;
    let mut env = Env::new(Town::default_town(), cfg).unwrap();
    let expert = Expert::default();
    for _ in 0..20 {
        env.step(expert.act(&env)).unwrap();
    }
    let view = BirdsEye::new(&BirdsEyeConfig::default()).unwrap();
    let plain = env.birdseye(&view);
    let mut drawn = plain.clone();
    let vc = env.cfg.vector.clone().unwrap();
    view.draw_vector(&mut drawn, env.ego.pos, env.ego.pos, env.ego.heading, env.vector().unwrap(), &vc, env.cfg.variant);
    let changed = plain.data.iter().zip(&drawn.data).filter(|(a, b)| a != b).count();
    assert!(changed > 100, "{changed} bytes drawn");
}
