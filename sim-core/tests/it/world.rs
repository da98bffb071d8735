//! The simulated world end to end: determinism, traffic safety, the reference driver on the
//! evaluation routes, episode ends, agent variants and the scenario options.

use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sim_core::collision::{CollisionKind, Obb, overlapping_pairs};
use sim_core::config::{EnvConfig, Variant};
use sim_core::env::{Env, EnvError, StepResult};
use sim_core::expert::Expert;
use sim_core::math::Vec2;
use sim_core::scenario::{EvalRoute, Scenario};
use sim_core::town::Town;
use sim_core::traffic::{EgoView, IdmParams, Traffic};
use sim_core::vehicle::{Action, VehicleParams};

/// Full throttle, no brake, wheel straight.
const FULL_THROTTLE: Action = Action::new(1.0, 0.0, 0.0);
/// Full brake.
const BRAKE: Action = Action::new(0.0, 1.0, 0.0);
/// Full throttle and full left lock (steer −1 is full left, vehicle.rs).
const FULL_LEFT: Action = Action::new(1.0, 0.0, -1.0);

/// The default configuration without the camera: nothing here looks at images, and the state,
/// rewards and collisions do not depend on rendering.
fn config() -> EnvConfig {
    EnvConfig { camera: None, ..EnvConfig::default() }
}

fn env_with(town: &Arc<Town>, cfg: EnvConfig) -> Env {
    Env::new(town.clone(), cfg).expect("valid configuration on the default town")
}

/// Steps with `policy` until the episode ends; returns every step's result.
fn run_episode(env: &mut Env, mut policy: impl FnMut(&Env) -> Action) -> Vec<StepResult> {
    let mut out = Vec::new();
    while !env.is_done() {
        let a = policy(env);
        out.push(env.step(a).expect("episode running"));
    }
    out
}

/// 1000 expert-driven steps from `Env::reset(seed, Random)` with 50 traffic and 12 parked cars,
/// resetting with seed + k when the k-th episode ends. Returns every step's `state_hash` and the
/// number of episodes started.
fn hashed_run(town: Arc<Town>, seed: u64) -> (Vec<u64>, u64) {
    let mut cfg = config();
    cfg.traffic.vehicles = 50;
    cfg.traffic.parked_cars = 12;
    let mut env = env_with(&town, cfg);
    env.reset(seed, Scenario::Random).expect("random route");
    let expert = Expert::default();
    let mut hashes = Vec::with_capacity(1000);
    let mut k = 0;
    for _ in 0..1000 {
        if env.is_done() {
            k += 1;
            env.reset(seed + k, Scenario::Random).expect("random route");
        }
        env.step(expert.act(&env)).expect("episode running");
        hashes.push(env.state_hash());
    }
    (hashes, k + 1)
}

#[test]
fn same_seed_gives_identical_trajectories() {
    // Two towns built independently from the embedded map, two environments.
    let (a, episodes) = hashed_run(Town::default_town(), 42);
    let (b, _) = hashed_run(Town::default_town(), 42);
    if let Some(i) = (0..a.len()).find(|&i| a[i] != b[i]) {
        panic!("trajectories diverge at step {i}");
    }
    // Episodes last at most time_limit = 200 steps (config/mod.rs default), so 1000 steps span at
    // least 5 of them: resets are part of what was compared.
    assert!(episodes >= 5, "only {episodes} episodes in 1000 steps");
    let (c, _) = hashed_run(Town::default_town(), 43);
    assert_ne!(a, c, "a different seed gave the same trajectory");
    let combine = |h: &[u64]| h.iter().fold(0u64, |acc, &x| acc.rotate_left(5) ^ x);
    assert_ne!(combine(&a), combine(&c));
}

#[test]
fn traffic_never_collides_with_itself_and_keeps_moving() {
    let town = Town::default_town();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut traffic = Traffic::empty(&town, IdmParams::default(), VehicleParams::default());
    traffic.spawn(&town, 60, &[], 0.0, &mut rng);
    // 60 cars 15 m apart fit easily on the default town's ~4 km of lanes: all are placed.
    assert_eq!(traffic.cars.len(), 60);
    let half = VehicleParams::default().half_extents();
    let far = EgoView { body: Obb::new(Vec2::new(-500.0, -500.0), half, 0.0), speed: 0.0, hold: None };
    let (mut speed_sum, mut samples) = (0.0f64, 0u64);
    let (mut late_sum, mut late_samples) = (0.0f64, 0u64);
    for t in 0..3000u64 {
        traffic.manage_junctions(&town, t, None, None);
        traffic.step(&town, &far, 0.1, &mut rng);
        let bodies: Vec<Obb> = traffic.bodies().map(|(b, _)| b).collect();
        let pairs = overlapping_pairs(&bodies);
        assert!(pairs.is_empty(), "step {t}: traffic cars overlap: {pairs:?}");
        for c in traffic.cars.iter().filter(|c| c.active && !c.parked) {
            speed_sum += f64::from(c.speed);
            samples += 1;
            if t >= 2000 {
                late_sum += f64::from(c.speed);
                late_samples += 1;
            }
        }
    }
    // Speed limits are 50–70 km/h (14–19 m/s); 2 m/s (7 km/h) on average means the town is
    // flowing, not gridlocked at its junctions. Checked over the whole run and its last 100 s.
    let mean = speed_sum / samples as f64;
    let late = late_sum / late_samples as f64;
    assert!(mean > 2.0, "mean traffic speed {mean} m/s");
    assert!(late > 2.0, "mean traffic speed over the last 1000 steps {late} m/s: gridlock?");
}

#[test]
fn expert_completes_every_evaluation_route_in_traffic() {
    expert_completes_every_route(&Town::default_town());
}

#[test]
fn expert_completes_every_evaluation_route_of_the_held_out_town() {
    let town = Town::embedded("held_out_town").expect("embedded");
    assert_eq!(town.map.name, "held_out_town");
    expert_completes_every_route(&town);
}

/// The reference driver completes each of the seven routes of `town` (two traffic seeds each)
/// without a collision: the routes exist, are drivable and are of their type.
fn expert_completes_every_route(town: &Arc<Town>) {
    // Default traffic: 20 moving cars and 12 parked ones (config/mod.rs).
    let cfg = config();
    assert_eq!(cfg.traffic.vehicles, 20);
    let mut env = env_with(town, cfg);
    let expert = Expert::default();
    for route in EvalRoute::ALL {
        for seed in [0, 1] {
            env.reset(seed, Scenario::Eval(route)).unwrap_or_else(|e| panic!("{} on {}: {e}", route.name(), town.map.name));
            let steps = run_episode(&mut env, |e| expert.act(e));
            let last = steps.last().expect("at least one step");
            assert!(
                last.info.arrived && last.terminated && last.info.collision.is_none(),
                "{} on {} seed {seed}: ended after {} steps with {:?}, arrived = {}, progress {}",
                route.name(),
                town.map.name,
                steps.len(),
                last.info.collision,
                last.info.arrived,
                last.info.progress
            );
            assert!(steps.iter().all(|s| s.info.collision.is_none()));
        }
    }
}

#[test]
fn collision_terminates_the_episode() {
    let town = Town::default_town();
    let cfg = config();
    let mut env = env_with(&town, cfg.clone());
    env.reset(0, Scenario::Eval(EvalRoute::StraightUrban)).expect("straight_urban");
    let steps = run_episode(&mut env, |_| FULL_LEFT);
    let last = steps.last().expect("at least one step");
    // Full left lock leaves the lane within a few seconds, long before the 300-step limit.
    assert!(last.info.collision.is_some(), "no collision: {:?}", last.info);
    assert!(steps.len() < cfg.eval_time_limit as usize);
    assert!(last.terminated && !last.truncated);
    assert_eq!(last.reward, cfg.reward.collision);
    assert!(!last.info.arrived);
    assert!(steps[..steps.len() - 1].iter().all(|s| !s.terminated && !s.truncated && s.info.collision.is_none()));
    assert_eq!(env.step(FULL_THROTTLE), Err(EnvError::EpisodeOver));

    // The same collision on the very step the time limit is reached: a terminal state, not a
    // truncation (the limit does not change the dynamics, so it happens at the same step).
    let n = steps.len();
    let mut env = env_with(&town, EnvConfig { eval_time_limit: n as u32, ..cfg.clone() });
    env.reset(0, Scenario::Eval(EvalRoute::StraightUrban)).expect("straight_urban");
    let again = run_episode(&mut env, |_| FULL_LEFT);
    assert_eq!(again.len(), n);
    let last = again.last().expect("at least one step");
    assert!(last.info.collision.is_some() && last.terminated && !last.truncated, "{last:?}");
}

#[test]
fn time_limit_truncates_the_episode() {
    let town = Town::default_town();
    let mut cfg = config();
    cfg.time_limit = 5;
    let mut env = env_with(&town, cfg.clone());
    env.reset(7, Scenario::Random).expect("random route");
    let steps = run_episode(&mut env, |_| BRAKE);
    assert_eq!(steps.len(), 5, "a 5-step limit");
    for s in &steps[..4] {
        assert!(!s.terminated && !s.truncated);
    }
    let last = &steps[4];
    assert!(last.truncated && !last.terminated, "{last:?}");
    assert_eq!(last.info.steps, 5);
    assert!(last.info.collision.is_none() && !last.info.arrived);
    // Truncation is not an outcome: the reward is the shaped one (standing still: r_v = −1).
    assert_eq!(last.reward, last.info.reward_terms.total);
    assert_eq!(last.info.reward_terms.r_v, -1.0);
    assert!(env.is_done());
    assert_eq!(env.step(BRAKE), Err(EnvError::EpisodeOver));
    // A reset starts over.
    env.reset(8, Scenario::Random).expect("random route");
    assert!(env.step(BRAKE).is_ok());
}

#[test]
fn variants_differ_only_in_observation_and_waypoint_reward() {
    let town = Town::default_town();
    let expert = Expert::default();
    let mut envs: Vec<Env> =
        [Variant::Hybrid, Variant::EndToEnd].into_iter().map(|variant| env_with(&town, EnvConfig { variant, ..config() })).collect();
    let d0 = envs[0].cfg.reward.d0;
    for (k, env) in envs.iter_mut().enumerate() {
        let obs = env.reset(5, Scenario::Eval(EvalRoute::LeftTurn)).expect("left_turn");
        assert_eq!(obs.d.is_some(), k == 0, "reset observation of variant {k}");
    }
    let mut driving_steps = 0;
    for step in 0..150 {
        let action = expert.act(&envs[0]);
        let hybrid = envs[0].step(action).expect("running");
        let e2e = envs[1].step(action).expect("running");
        // The variant changes neither the world nor d, only what the agent sees and is paid.
        assert_eq!(envs[0].state_hash(), envs[1].state_hash(), "step {step}");
        assert_eq!(hybrid.info.d, e2e.info.d);
        assert_eq!(hybrid.observation.d, Some(hybrid.info.d), "step {step}");
        assert_eq!(e2e.observation.d, None, "step {step}");
        assert_eq!(e2e.info.reward_terms.r_w, 0.0, "step {step}");
        if !hybrid.terminated {
            driving_steps += 1;
            // r_w = 1 − d/d0 (reward.rs, the paper's eq. 7).
            assert!((hybrid.info.reward_terms.r_w - (1.0 - hybrid.info.d / d0)).abs() < 1e-5, "step {step}");
            let (h, e) = (hybrid.info.reward_terms, e2e.info.reward_terms);
            assert_eq!((h.r_v, h.r_l), (e.r_v, e.r_l));
            assert!((h.total - e.total - h.r_w).abs() < 1e-5, "step {step}: totals differ by more than r_w");
        }
        if hybrid.terminated || hybrid.truncated {
            break;
        }
    }
    assert!(driving_steps > 50, "only {driving_steps} driving steps compared");
}

#[test]
fn parked_car_ahead_blocks_the_lane() {
    let town = Town::default_town();
    let mut cfg = config();
    cfg.traffic.vehicles = 0;
    cfg.traffic.parked_car_ahead = Some(10.0);
    let mut env = env_with(&town, cfg);
    env.reset(0, Scenario::Eval(EvalRoute::StraightUrban)).expect("straight_urban");
    let parked: Vec<usize> = (0..env.traffic.cars.len()).filter(|&i| env.traffic.cars[i].parked).collect();
    assert_eq!(parked.len(), 1, "with no traffic, the only traffic car is the parked one");
    let car = parked[0];
    let proj = env.route.path.project(env.traffic.cars[car].pos);
    assert!((proj.s - 10.0).abs() < 0.5, "parked car {} m along the route, asked for 10", proj.s);
    assert!(proj.lateral.abs() < 0.3, "parked car {} m off the route's centre line", proj.lateral);

    let steps = run_episode(&mut env, |_| FULL_THROTTLE);
    let last = steps.last().expect("at least one step");
    assert_eq!(last.info.collision, Some(CollisionKind::ParkedCar));
    assert!(env.ego_body().intersects(&env.traffic.body(car)), "the ego hit some other parked car");
    // Bumpers meet when the ego's centre is 10 − 4.5 = 5.5 m along (two half lengths of 2.25 m),
    // detected within one step of travel (< 1 m at these speeds).
    assert!((5.4..6.6).contains(&env.tracking.s), "collision at s = {}", env.tracking.s);
}

#[test]
fn random_routes_respect_the_length_range() {
    let town = Town::default_town();
    let mut env = env_with(&town, config());
    let (min, max) = (env.cfg.route_length_min, env.cfg.route_length_max);
    for seed in 0..50 {
        env.reset(seed, Scenario::Random).expect("random route");
        let len = env.route.length();
        assert!((min..=max).contains(&len), "seed {seed}: route of {len} m outside [{min}, {max}]");
        assert_eq!(env.ego.pos, env.route.path.start(), "seed {seed}: ego not at the route's start");
    }
    // A narrow custom range is honoured too.
    let mut cfg = config();
    (cfg.route_length_min, cfg.route_length_max) = (100.0, 110.0);
    let mut env = env_with(&town, cfg);
    for seed in 0..20 {
        env.reset(seed, Scenario::Random).expect("random route");
        let len = env.route.length();
        assert!((100.0..=110.0).contains(&len), "seed {seed}: route of {len} m outside [100, 110]");
    }
}

#[test]
fn path_features_preview_the_turn_and_point_the_way_back_to_the_route() {
    let town = Town::default_town();
    let expert = Expert::default();
    for (route, sign) in [(EvalRoute::LeftTurn, 1.0), (EvalRoute::RightTurn, -1.0)] {
        let mut env = env_with(&town, config());
        let obs = env.reset(3, Scenario::Eval(route)).expect("turn route");
        assert_eq!(obs.path, Some(env.path_features()));
        // The expert follows the route: it stays near the centre line, and before the junction the
        // far preview turns toward the side of the turn while the near angle stays small.
        let (mut far_max, mut near_max) = (0.0f32, 0.0f32);
        for _ in 0..150 {
            let [lateral, near, far] = env.path_features();
            assert!(lateral.abs() < 2.0, "{route:?}: lateral {lateral}");
            far_max = far_max.max(sign * far);
            near_max = near_max.max(near.abs());
            if env.step(expert.act(&env)).expect("running").terminated {
                break;
            }
        }
        assert!(far_max > 0.5, "{route:?}: far preview never pointed into the turn ({far_max} rad)");
        assert!(near_max < far_max, "{route:?}: near angle {near_max} rad, far {far_max} rad");
    }
    // Off the centre line, to the left of the route: the lateral offset is positive and both
    // angles point back to the right (negative).
    let mut env = env_with(&town, config());
    env.reset(3, Scenario::Eval(EvalRoute::StraightHighway)).expect("straight route");
    let left = sim_core::math::left_normal(env.route.path.tangent_at(env.tracking.s));
    env.ego.pos += left * 1.5;
    env.tracking.lateral += 1.5;
    let [lateral, near, far] = env.path_features();
    assert!(lateral > 1.0 && near < -0.05 && far < 0.0, "lateral {lateral}, near {near}, far {far}");
    let mut e2e = env_with(&town, EnvConfig { variant: Variant::EndToEnd, ..config() });
    assert_eq!(e2e.reset(3, Scenario::Eval(EvalRoute::StraightHighway)).expect("straight").path, None);
}

#[test]
fn both_towns_routes_are_of_their_type() {
    use sim_core::scenario::eval_route;
    for town in [Town::default_town(), Town::embedded("held_out_town").unwrap()] {
        for route in EvalRoute::ALL {
            let r = eval_route(&town, route, 8.0).unwrap_or_else(|| panic!("{} on {}: no route", route.name(), town.map.name));
            let (a, b) = (r.path.heading_at(0.0), r.path.heading_at(r.path.length()));
            let turn = libm::remainderf(b - a, std::f32::consts::TAU).to_degrees();
            let ok = match route {
                EvalRoute::StraightHighway | EvalRoute::StraightUrban | EvalRoute::StraightUnderBridge => turn.abs() < 5.0,
                EvalRoute::SlightCurve => (10.0..40.0).contains(&turn.abs()),
                EvalRoute::SharpCurve => (80.0..100.0).contains(&turn.abs()),
                EvalRoute::RightTurn => (-100.0..-80.0).contains(&turn),
                EvalRoute::LeftTurn => (80.0..100.0).contains(&turn),
            };
            assert!(ok, "{} on {}: turns {turn:.1}° over {:.0} m", route.name(), town.map.name, r.length());
            assert!((80.0..300.0).contains(&r.length()), "{} on {}: {:.0} m", route.name(), town.map.name, r.length());
        }
    }
}

#[test]
fn a_stacked_observation_holds_the_last_frames_oldest_first() {
    let town = Town::default_town();
    let camera = sim_core::camera::CameraConfig { width: 16, height: 16, stack: 3, ..Default::default() };
    let mut env = env_with(&town, EnvConfig { camera: Some(camera), ..EnvConfig::default() });
    let obs = env.reset(4, Scenario::Random).unwrap();
    let first = env.image().clone();
    let stacked = obs.image.unwrap();
    assert_eq!((stacked.width, stacked.height, stacked.channels), (16, 16, 3));
    // At the start every frame of the stack is the first.
    assert!(stacked.data.chunks_exact(3).zip(&first.data).all(|(px, &f)| px == [f, f, f]));
    let mut history = vec![first.clone(), first.clone(), first];
    for step in 1..=4 {
        let stacked = env.step(FULL_THROTTLE).unwrap().observation.image.unwrap();
        history.remove(0);
        history.push(env.image().clone());
        let want: Vec<u8> = (0..256).flat_map(|p| [history[0].data[p], history[1].data[p], history[2].data[p]]).collect();
        assert_eq!(stacked.data, want, "after {step} steps");
    }
    assert_ne!(history[0], history[2], "the frames differ: the test would pass on a stack of copies");
    // A stack of one is the camera's image, as before stacking existed.
    let mut single = env_with(
        &town,
        EnvConfig { camera: Some(sim_core::camera::CameraConfig { width: 16, height: 16, ..Default::default() }), ..EnvConfig::default() },
    );
    let obs = single.reset(4, Scenario::Random).unwrap();
    assert_eq!(obs.image.as_ref(), Some(single.image()));
}
