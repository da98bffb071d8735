//! Hazards end to end: each kind is placed on the route ahead (never inside the ego nor off the
//! route), visible, collidable, scripted as its kind says, and deterministic per seed; hazards off
//! leaves episodes as they were.

use sim_core::collision::{CollisionKind, Obb};
use sim_core::config::EnvConfig;
use sim_core::env::{Env, StepResult};
use sim_core::expert::Expert;
use sim_core::hazards::{HazardKind, HazardsConfig};
use sim_core::planner::PlannerKind;
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

fn avoid_config(kind: HazardKind) -> EnvConfig {
    EnvConfig { planner: PlannerKind::AstarAvoid, ..config(kind) }
}

/// The kinds placed on random routes: all of them.
const PLACED: [HazardKind; 7] = HazardKind::ALL;

/// How each of seeds 0..n ends: (collision, arrived).
fn outcomes(cfg: &EnvConfig, expert: &Expert, n: u64) -> Vec<(Option<CollisionKind>, bool)> {
    let mut env = Env::new(Town::default_town(), cfg.clone()).unwrap();
    (0..n)
        .map(|seed| {
            env.reset(seed, Scenario::Random).unwrap();
            let last = drive(&mut env, expert).pop().unwrap();
            (last.info.collision, last.info.arrived)
        })
        .collect()
}

#[test]
fn every_kind_is_placed_ahead_on_the_route_never_inside_the_ego() {
    for town in [Town::default_town(), Town::embedded("held_out_town").unwrap()] {
        for kind in PLACED {
            let mut env = Env::new(town.clone(), config(kind)).unwrap();
            for seed in 0..6 {
                env.reset(seed, Scenario::Random).unwrap();
                let h = env.hazard.clone().unwrap_or_else(|| panic!("{kind:?} seed {seed}: no hazard"));
                assert_eq!(h.kind, kind);
                assert_eq!(env.info().hazard.map(|i| i.kind), Some(kind));
                assert!(h.s >= 15.0 && h.s <= env.route.length() - 20.0, "{kind:?} at {} of {}", h.s, env.route.length());
                let ego = env.ego_body();
                let mut bodies: Vec<Obb> = h.props.iter().map(|p| p.body).collect();
                bodies.extend(h.walkers.iter().map(|w| w.body()));
                bodies.extend(h.car.map(|i| env.traffic.body(i)));
                assert!(!bodies.is_empty());
                for b in bodies {
                    assert!(!b.intersects(&ego), "{kind:?} seed {seed}: inside the ego");
                    if kind == HazardKind::JunctionRunner {
                        continue; // it waits on a road into the junction: checked below
                    }
                    let p = env.route.path.project(b.centre);
                    assert!(p.distance < 8.0 && p.s > 10.0, "{kind:?} seed {seed}: off the route ({p:?})");
                }
                if kind == HazardKind::JunctionRunner {
                    // Its lane leads into a junction of the route, onto a connector that conflicts
                    // with the route's there.
                    let runner = &env.traffic.cars[h.car.unwrap()];
                    let into = runner.next.unwrap();
                    let ego_connector = env.route.lane_at(h.s);
                    assert!(env.town.is_connector(ego_connector), "seed {seed}: the crossing point is in a junction");
                    assert!(env.town.connectors_conflict(into, ego_connector), "seed {seed}: the runner's path crosses the route's");
                    assert!(env.town.map.lanes[runner.lane].successors.contains(&into));
                }
            }
        }
    }
}

#[test]
fn same_seed_gives_identical_trajectories_and_frames_with_hazards() {
    let run = |kind: HazardKind, seed: u64| {
        let cfg = EnvConfig { camera: Some(Default::default()), ..avoid_config(kind) };
        let mut env = Env::new(Town::default_town(), cfg).unwrap();
        env.reset(seed, Scenario::Random).unwrap();
        let expert = Expert::avoiding();
        let mut hashes = Vec::new();
        for _ in 0..120 {
            if env.is_done() {
                break;
            }
            let r = env.step(expert.act(&env)).unwrap();
            hashes.push((env.state_hash(), r.observation.image.unwrap().hash(), r.reward.to_bits()));
        }
        hashes
    };
    for kind in PLACED {
        let a = run(kind, 3);
        assert!(a.len() > 50, "{kind:?}");
        assert_eq!(a, run(kind, 3), "{kind:?}");
        assert_ne!(a, run(kind, 4), "{kind:?}");
    }
}

#[test]
fn an_episode_drawn_without_a_hazard_is_the_episode_with_hazards_off() {
    let off = EnvConfig { camera: None, ..EnvConfig::default() };
    let half = EnvConfig { hazards: HazardsConfig { rate: 0.5, ..HazardsConfig::default() }, ..off.clone() };
    let (mut a, mut b) = (Env::new(Town::default_town(), off).unwrap(), Env::new(Town::default_town(), half).unwrap());
    let (mut with, mut without) = (0, 0);
    for seed in 0..16 {
        a.reset(seed, Scenario::Random).unwrap();
        b.reset(seed, Scenario::Random).unwrap();
        if b.hazard.is_some() {
            with += 1;
            continue;
        }
        without += 1;
        let expert = Expert::default();
        for _ in 0..60 {
            if a.is_done() {
                break;
            }
            a.step(expert.act(&a)).unwrap();
            b.step(expert.act(&b)).unwrap();
            assert_eq!(a.state_hash(), b.state_hash(), "seed {seed}");
        }
    }
    assert!(with > 2 && without > 2, "rate 0.5: {with} with, {without} without");
}

#[test]
fn draws_beyond_training_reach_the_episode() {
    let kind = HazardKind::PedestrianCrossing;
    let cfg = EnvConfig { hazards: HazardsConfig::beyond_training(kind), ..config(kind) };
    let mut env = Env::new(Town::default_town(), cfg).unwrap();
    for seed in 0..5 {
        env.reset(seed, Scenario::Random).unwrap();
        let h = env.hazard.clone().unwrap_or_else(|| panic!("seed {seed}: no hazard"));
        assert!(!h.walkers.is_empty());
        assert!(h.walkers.iter().all(|w| (1.8..=2.4).contains(&w.speed)), "seed {seed}: {:?}", h.walkers);
    }
}

#[test]
fn stalled_car_stops_the_blind_driver_and_the_avoiding_one_passes_it() {
    let blind = outcomes(&config(HazardKind::StalledCar), &Expert::default(), 5);
    assert!(blind.iter().all(|&(c, arrived)| c.is_none() && !arrived), "the blind driver waits behind it: {blind:?}");
    let avoid = outcomes(&avoid_config(HazardKind::StalledCar), &Expert::avoiding(), 6);
    assert!(avoid.iter().filter(|o| o.1).count() >= 4, "{avoid:?}");
    assert!(!avoid.iter().any(|o| o.0 == Some(CollisionKind::ParkedCar)), "{avoid:?}");
}

#[test]
fn pedestrian_crossing_is_hit_blind_and_braked_for_when_perceived() {
    let blind = outcomes(&config(HazardKind::PedestrianCrossing), &Expert::default(), 5);
    assert!(blind.iter().filter(|o| o.0 == Some(CollisionKind::Pedestrian)).count() >= 4, "{blind:?}");
    let avoid = outcomes(&avoid_config(HazardKind::PedestrianCrossing), &Expert::avoiding(), 6);
    assert!(!avoid.iter().any(|o| o.0 == Some(CollisionKind::Pedestrian)), "{avoid:?}");
    assert!(avoid.iter().filter(|o| o.1).count() >= 4, "{avoid:?}");
}

#[test]
fn construction_is_hit_blind_and_driven_round_when_perceived() {
    let blind = outcomes(&config(HazardKind::Construction), &Expert::default(), 5);
    assert!(blind.iter().filter(|o| o.0 == Some(CollisionKind::Construction)).count() >= 3, "{blind:?}");
    let avoid = outcomes(&avoid_config(HazardKind::Construction), &Expert::avoiding(), 6);
    assert!(!avoid.iter().any(|o| o.0 == Some(CollisionKind::Construction)), "{avoid:?}");
    assert!(avoid.iter().filter(|o| o.1).count() >= 4, "{avoid:?}");
}

#[test]
fn hard_brake_leader_stops_at_its_limit_and_car_following_suffices() {
    let mut env = Env::new(Town::default_town(), config(HazardKind::HardBrake)).unwrap();
    env.reset(0, Scenario::Random).unwrap();
    let i = env.hazard.as_ref().unwrap().car.unwrap();
    let expert = Expert::default();
    let (mut stopped, mut decel) = (false, 0.0f32);
    let mut prev = env.traffic.cars[i].speed;
    while !env.is_done() {
        env.step(expert.act(&env)).unwrap();
        let v = env.traffic.cars[i].speed;
        decel = decel.max((prev - v) / 0.1);
        stopped |= env.hazard.as_ref().unwrap().triggered && v == 0.0;
        prev = v;
    }
    assert!(stopped && decel > 8.0, "braked at {decel} m/s², stopped: {stopped}");
    let blind = outcomes(&config(HazardKind::HardBrake), &Expert::default(), 5);
    assert!(!blind.iter().any(|o| o.0 == Some(CollisionKind::Vehicle)), "{blind:?}");
}

#[test]
fn cut_in_car_ends_in_the_ego_lane_ahead() {
    let mut env = Env::new(Town::default_town(), config(HazardKind::CutIn)).unwrap();
    env.reset(1, Scenario::Random).unwrap();
    let i = env.hazard.as_ref().unwrap().car.unwrap();
    let first_lane = env.traffic.cars[i].lane;
    let expert = Expert::default();
    let mut merged = false;
    while !env.is_done() && !merged {
        env.step(expert.act(&env)).unwrap();
        let c = &env.traffic.cars[i];
        let ahead = env.route.path.project(c.pos).s - env.tracking.s;
        merged = env.hazard.as_ref().unwrap().triggered && c.lateral.abs() < 1.0 && c.lane != first_lane;
        if merged {
            assert!(ahead > 4.5, "it cut in ahead of the ego: {ahead} m");
        }
    }
    assert!(merged, "the car never cut in: {:?} {:?}", env.info(), env.hazard);
}

#[test]
fn cut_in_starts_its_lane_change_within_the_drawn_gap_of_the_ego_slower_than_it() {
    let gap = HazardsConfig::default().cut_in_gap;
    for town in [Town::default_town(), Town::embedded("held_out_town").unwrap()] {
        let mut env = Env::new(town, config(HazardKind::CutIn)).unwrap();
        let expert = Expert::default();
        for seed in 0..10 {
            env.reset(seed, Scenario::Random).unwrap();
            let i = env.hazard.as_ref().unwrap().car.unwrap();
            let mut change = None;
            while !env.is_done() && change.is_none() {
                env.step(expert.act(&env)).unwrap();
                if env.hazard.as_ref().unwrap().triggered {
                    let c = &env.traffic.cars[i];
                    // Bumper to bumper along the route, after the step that started it (the car
                    // has driven on one step since it measured the gap).
                    let ahead = env.route.path.project(c.pos).s
                        - env.tracking.s
                        - env.cfg.vehicle.length / 2.0
                        - env.traffic.body(i).half.x
                        - c.speed * env.cfg.dt;
                    change = Some((ahead, c.speed, env.ego.speed));
                }
            }
            let (ahead, speed, ego_speed) = change.unwrap_or_else(|| panic!("seed {seed}: no cut-in: {:?}", env.info()));
            assert!(ahead > gap.min - 1.0 && ahead <= gap.max + 0.5, "seed {seed}: changed lanes {ahead} m ahead of the ego");
            assert!(speed < ego_speed && speed > 0.5 * ego_speed, "seed {seed}: at {speed} m/s, the ego at {ego_speed}");
        }
    }
}

#[test]
fn opposite_overtaker_pulls_into_the_ego_lane_and_back() {
    let mut env = Env::new(Town::default_town(), avoid_config(HazardKind::OppositeOvertaker)).unwrap();
    env.reset(0, Scenario::Random).unwrap();
    let i = env.hazard.as_ref().unwrap().car.unwrap();
    let expert = Expert::avoiding();
    let (mut out, mut back) = (false, false);
    while !env.is_done() {
        env.step(expert.act(&env)).unwrap();
        let lat = env.traffic.cars[i].lateral;
        out |= lat > 3.0;
        back |= out && lat == 0.0;
    }
    assert!(out && back, "out {out}, back {back}");
    assert!(env.info().arrived, "the avoiding driver lets it pass: {:?}", env.info());
}

#[test]
fn junction_runner_crosses_without_right_of_way_hits_the_blind_driver_and_is_stopped_for_when_perceived() {
    let mut env = Env::new(Town::default_town(), config(HazardKind::JunctionRunner)).unwrap();
    env.reset(0, Scenario::Random).unwrap();
    let i = env.hazard.as_ref().unwrap().car.unwrap();
    let (approach, expert) = (env.traffic.cars[i].lane, Expert::default());
    let mut entered_while_ego_held = false;
    while !env.is_done() {
        env.step(expert.act(&env)).unwrap();
        let c = &env.traffic.cars[i];
        entered_while_ego_held |= c.lane != approach && env.ego_hold().is_some_and(|h| env.town.connectors_conflict(h, c.lane));
    }
    assert!(entered_while_ego_held, "it takes its connector while the ego holds a conflicting one");
    let blind = outcomes(&config(HazardKind::JunctionRunner), &Expert::default(), 6);
    assert!(blind.iter().filter(|o| o.0 == Some(CollisionKind::Vehicle)).count() >= 3, "{blind:?}");
    let avoid = outcomes(&avoid_config(HazardKind::JunctionRunner), &Expert::avoiding(), 6);
    assert!(!avoid.iter().any(|o| o.0 == Some(CollisionKind::Vehicle)), "{avoid:?}");
    assert!(avoid.iter().filter(|o| o.1).count() >= 4, "{avoid:?}");
}
