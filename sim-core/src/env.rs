//! An episode of driving: `reset(seed, scenario)` and `step(action)`, returning the observation,
//! the reward (`reward.rs`), termination (collision, arrival), truncation (time limit) and diagnostics.

use std::sync::Arc;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::camera::{BirdsEye, Camera, FrameStack, Image, SceneBox, car_box, prop_box, walker_box};
use crate::collision::{CollisionKind, Obb, leaves_drivable_area};
use crate::config::{ConfigError, EnvConfig, Variant};
use crate::hash::Fnv1a64;
use crate::hazards::spawn::{feasible, place};
use crate::hazards::walker::WALKER_HEIGHT;
use crate::hazards::{Hazard, HazardInfo};
use crate::map::LaneId;
use crate::math::{Vec2, left_normal};
pub use crate::path_features::PATH_FEATURES;
use crate::path_features::{path_features, path_features_along};
use crate::planner::{Detour, LocalPlanner, Planner, WorldView};
use crate::reward::{Outcome, RewardTerms, StepMeasures};
use crate::route::{Route, RouteTracker, Tracking};
use crate::scenario::{Scenario, eval_route, random_route};
use crate::sensor::ego_path::PathInput;
use crate::sensor::{Sensor, World};
use crate::town::Town;
use crate::traffic::{EgoRequest, EgoView, RELEASE_DISTANCE, Traffic};
use crate::vehicle::{Action, VehicleState};

/// What the agent observes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Observation {
    /// Ego speed, m/s.
    pub speed: f32,
    /// Distance to the closest route waypoint, metres (hybrid variant only).
    pub d: Option<f32>,
    /// The planner's path relative to the ego vehicle (hybrid variant only): see
    /// [`Env::path_features`].
    pub path: Option<[f32; PATH_FEATURES]>,
    /// The front camera's image, if a camera is configured: its last `stack` frames stacked
    /// ([`Env::stacked_image`]).
    #[serde(skip)]
    pub image: Option<Image>,
    /// The vector sensor's reading, if `[env.vector]` is configured (`sensor`).
    pub vector: Option<Vec<f32>>,
}

/// Diagnostics of a step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepInfo {
    /// Distance to the closest waypoint ahead, metres.
    pub d: f32,
    /// Straight-line distance to the destination, metres.
    pub l: f32,
    /// m/s.
    pub speed: f32,
    /// What the ego hit this step, if anything.
    pub collision: Option<CollisionKind>,
    /// Fraction of the route's length driven, 0 to 1.
    pub progress: f32,
    pub arrived: bool,
    pub reward_terms: RewardTerms,
    /// Steps since reset.
    pub steps: u32,
    /// The episode's hazard, if it has one.
    pub hazard: Option<HazardInfo>,
}

/// The result of one step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepResult {
    pub observation: Observation,
    pub reward: f32,
    /// The episode ended in a terminal state (collision or arrival): do not bootstrap.
    pub terminated: bool,
    /// The episode hit its time limit: not a terminal state (bootstrap through it).
    pub truncated: bool,
    pub info: StepInfo,
}

/// An environment could not start an episode.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnvError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("scenario `{0}` needs the default town's roads, which this map lacks")]
    ScenarioNotOnMap(&'static str),
    #[error("no random route of {min}–{max} m could be found on this map")]
    NoRandomRoute { min: f32, max: f32 },
    #[error("step called on a finished episode: call reset first")]
    EpisodeOver,
}

/// One driving environment. Plain data: cloneable, `Send`, no threads or I/O.
#[derive(Debug, Clone)]
pub struct Env {
    pub town: Arc<Town>,
    pub cfg: EnvConfig,
    pub ego: VehicleState,
    pub traffic: Traffic,
    /// Cars parked on shoulders.
    pub parked: Vec<Obb>,
    pub route: Route,
    pub tracking: Tracking,
    /// The episode's hazard (see `hazards`), unknown to the route and the observation.
    pub hazard: Option<Hazard>,
    /// The planner of the waypoints (`[env] planner`).
    planner: LocalPlanner,
    rng: ChaCha8Rng,
    tracker: RouteTracker,
    steps: u32,
    time_limit: u32,
    l_prev: f32,
    /// The route arc length before the step (the progress reward's Δs).
    s_prev: f32,
    /// Steps since the environment was created (orders junction requests).
    clock: u64,
    ego_hold: Option<LaneId>,
    ego_request: Option<EgoRequest>,
    /// Junctions the ego entered without holding their connector, this episode.
    right_of_way_violations: u32,
    done: bool,
    last_info: StepInfo,
    camera: Option<Camera>,
    image: Image,
    /// The last frames, with `[env.camera] stack` > 1.
    frames: Option<FrameStack>,
    /// Scratch: the vehicles as the renderers see them.
    scene: Vec<SceneBox>,
    /// The vector sensor's last reading (empty without `[env.vector]`).
    vector: Vec<f32>,
    /// The vector sensor's buffers.
    sensor: Sensor,
    /// The ego's speed before the last step (0 at reset): the sensor's acceleration.
    prev_speed: f32,
}

impl Env {
    /// An environment on `town` with `cfg` (validated), reset to a random episode with seed 0.
    pub fn new(town: Arc<Town>, cfg: EnvConfig) -> Result<Self, EnvError> {
        cfg.validate()?;
        let camera = cfg.camera.as_ref().map(Camera::new).transpose()?;
        let frames = cfg.camera.as_ref().filter(|c| c.stack > 1).map(|c| FrameStack::new(c.stack as usize));
        let planner_kind = cfg.planner;
        let traffic = Traffic::empty(&town, cfg.traffic.idm, cfg.vehicle);
        let dummy = crate::route::Route {
            path: crate::polyline::Polyline::new([Vec2::ZERO, Vec2::X]).expect("two points"),
            waypoints: vec![Vec2::ZERO],
            lanes: vec![(0, 0.0)],
            cost: 0.0,
        };
        let mut env = Self {
            town,
            cfg,
            ego: VehicleState::at_rest(Vec2::ZERO, 0.0),
            traffic,
            parked: Vec::new(),
            route: dummy,
            hazard: None,
            planner: LocalPlanner::new(planner_kind),
            tracking: Tracking { d: 0.0, s: 0.0, lateral: 0.0 },
            rng: ChaCha8Rng::seed_from_u64(0),
            tracker: RouteTracker::default(),
            steps: 0,
            time_limit: 1,
            l_prev: 0.0,
            s_prev: 0.0,
            clock: 0,
            ego_hold: None,
            ego_request: None,
            right_of_way_violations: 0,
            done: true,
            last_info: StepInfo {
                d: 0.0,
                l: 0.0,
                speed: 0.0,
                collision: None,
                progress: 0.0,
                arrived: false,
                reward_terms: RewardTerms::default(),
                steps: 0,
                hazard: None,
            },
            camera,
            image: Image::new(0, 0, 1),
            frames,
            scene: Vec::new(),
            vector: Vec::new(),
            sensor: Sensor::default(),
            prev_speed: 0.0,
        };
        env.reset(0, Scenario::Random)?;
        Ok(env)
    }

    /// Starts an episode. Everything random in it (route, traffic, parking) comes from `seed`.
    pub fn reset(&mut self, seed: u64, scenario: Scenario) -> Result<Observation, EnvError> {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
        // The hazard comes from a stream of its own, so that hazards off (or an episode drawn
        // without one) leaves everything else as it was.
        let mut hazard_rng = ChaCha8Rng::seed_from_u64(seed);
        hazard_rng.set_stream(HAZARD_STREAM);
        let hz = &self.cfg.hazards;
        let kind =
            (hz.rate > 0.0 && hazard_rng.random_bool(f64::from(hz.rate))).then(|| hz.kinds[hazard_rng.random_range(0..hz.kinds.len())]);
        let cfg = &self.cfg;
        let (route, time_limit) = match scenario {
            Scenario::Random => {
                let draw = |rng: &mut ChaCha8Rng| {
                    random_route(&self.town, cfg.route_length_min, cfg.route_length_max, cfg.waypoint_spacing, rng)
                        .ok_or(EnvError::NoRandomRoute { min: cfg.route_length_min, max: cfg.route_length_max })
                };
                let mut route = draw(&mut self.rng)?;
                // A hazard episode draws routes until one has room for its kind.
                if let Some(k) = kind {
                    for _ in 0..HAZARD_ROUTE_TRIES {
                        if feasible(k, hz, &self.town, &route).is_some() {
                            break;
                        }
                        route = draw(&mut self.rng)?;
                    }
                }
                (route, cfg.time_limit)
            }
            Scenario::Eval(r) => {
                (eval_route(&self.town, r, cfg.waypoint_spacing).ok_or(EnvError::ScenarioNotOnMap(r.name()))?, cfg.eval_time_limit)
            }
        };
        let start = route.path.start();
        let heading = route.path.heading_at(0.0);
        self.ego = VehicleState::at_rest(start, heading);
        self.route = route;
        self.tracker = RouteTracker::default();
        self.tracking = self.tracker.update(&self.route, start);
        self.steps = 0;
        self.time_limit = time_limit;
        self.l_prev = start.distance(self.route.destination());
        self.s_prev = self.tracking.s;
        self.ego_hold = None;
        self.ego_request = None;
        self.right_of_way_violations = 0;
        self.done = false;
        self.prev_speed = 0.0;
        self.sensor.clear();

        self.traffic = Traffic::empty(&self.town, self.cfg.traffic.idm, self.cfg.vehicle);
        if let Some(ahead) = self.cfg.traffic.parked_car_ahead {
            let s = ahead.min(self.route.length() - 1.0);
            let lane = self.route.lane_at(s);
            let p = self.route.path.point_at(s);
            let lane_s = self.town.map.lanes[lane].path.project(p).s;
            self.traffic.add_parked_on_lane(&self.town, lane, lane_s);
        }
        // Keep the start and the first stretch of the route clear of spawned traffic.
        let avoid = [start, self.route.path.point_at(15.0)];
        self.traffic.spawn(&self.town, self.cfg.traffic.vehicles, &avoid, self.cfg.traffic.spawn_clearance, &mut self.rng);
        self.parked = self.place_parked_cars(self.cfg.traffic.parked_cars, start);
        self.hazard = kind.and_then(|k| place(k, &self.cfg.hazards, &self.town, &self.route, &mut self.traffic, &mut hazard_rng));
        if let Some(h) = &self.hazard {
            // Shoulders free around the hazard: room to pass it, and no second obstacle.
            let route = &self.route;
            self.parked.retain(|p| {
                let proj = route.path.project(p.centre);
                !(proj.s > h.s - 25.0 && proj.s < h.s + 70.0 && proj.distance < 8.0)
            });
        }
        self.planner = LocalPlanner::new(self.cfg.planner);
        self.update_planner();
        self.last_info = self.info_now(None, false, RewardTerms::default());
        self.render();
        if let Some(f) = &mut self.frames {
            f.reset(&self.image);
        }
        self.sense();
        Ok(self.observation())
    }

    /// Advances one step under `action`.
    pub fn step(&mut self, action: Action) -> Result<StepResult, EnvError> {
        if self.done {
            return Err(EnvError::EpisodeOver);
        }
        let dt = self.cfg.dt;
        self.prev_speed = self.ego.speed;
        self.ego.step(&self.cfg.vehicle, action, dt);
        self.tracking = self.tracker.update(&self.route, self.ego.pos);
        self.update_ego_junction();
        let granted = self.traffic.manage_junctions(&self.town, self.clock, self.ego_hold, self.ego_request);
        if granted {
            self.ego_hold = self.ego_request.take().map(|r| r.connector);
        }
        if let Some(h) = &mut self.hazard {
            h.step(&self.town, &self.route, &mut self.traffic, &self.ego, self.tracking.s, dt);
        }
        let body = self.ego_body();
        let view = EgoView { body, speed: self.ego.speed, hold: self.ego_hold };
        self.traffic.step(&self.town, &view, dt, &mut self.rng);
        self.clock += 1;
        self.steps += 1;

        self.update_planner();
        let collision = self.collision(&body);
        let l = self.ego.pos.distance(self.route.destination());
        let arrived = collision.is_none() && self.cfg.reward.arrived(l);
        let outcome = match (collision, arrived) {
            (Some(_), _) => Outcome::Collision,
            (None, true) => Outcome::Arrived,
            (None, false) => Outcome::Driving,
        };
        let planned = self.planned_tracking();
        let measures = StepMeasures {
            speed: self.ego.speed,
            l,
            l_prev: self.l_prev,
            d: planned.d,
            ds: self.tracking.s - self.s_prev,
            lateral: planned.lateral,
            dt,
        };
        let terms = self.cfg.reward.reward(self.cfg.variant, outcome, &measures);
        self.l_prev = l;
        self.s_prev = self.tracking.s;
        let terminated = outcome != Outcome::Driving;
        let truncated = !terminated && self.steps >= self.time_limit;
        self.done = terminated || truncated;
        self.last_info = self.info_now(collision, arrived, terms);
        self.render();
        if let Some(f) = &mut self.frames {
            f.push(&self.image);
        }
        self.sense();
        Ok(StepResult { observation: self.observation(), reward: terms.total, terminated, truncated, info: self.last_info.clone() })
    }

    /// The current observation.
    #[must_use]
    pub fn observation(&self) -> Observation {
        Observation {
            speed: self.ego.speed,
            d: (self.cfg.variant == Variant::Hybrid).then(|| self.planned_tracking().d),
            path: (self.cfg.variant == Variant::Hybrid).then(|| self.path_features()),
            image: self.camera.is_some().then(|| self.stacked_image().clone()),
            vector: self.vector().map(<[f32]>::to_vec),
        }
    }

    /// The planner's path as seen from the ego vehicle, beyond the paper's d (which has no sign and
    /// no direction): the signed lateral offset from the route's centre line (metres, positive to
    /// the left), the angle from the ego heading to the route point a speed-dependent preview
    /// distance ahead (radians, positive to the left), and the same angle to the route point 25 m
    /// ahead, which previews turns and curves. Defined in `path_features.rs`.
    #[must_use]
    pub fn path_features(&self) -> [f32; PATH_FEATURES] {
        match self.planner.detour() {
            None => path_features(&self.route, &self.tracking, &self.ego),
            Some(d) => path_features_along(|s| bent_point(&self.route, &d, s), &self.planned_tracking(), &self.ego),
        }
    }

    /// The planner's path at route arc length `s`: the route's point, shifted by its detour.
    #[must_use]
    pub fn planned_point(&self, s: f32) -> Vec2 {
        match self.planner.detour() {
            None => self.route.path.point_at(s),
            Some(d) => bent_point(&self.route, &d, s),
        }
    }

    /// The planner's detour from the route, if it asks for one.
    #[must_use]
    pub fn detour(&self) -> Option<Detour> {
        self.planner.detour()
    }

    /// The route arc length the planner asks to stop at (no way round is clear), if any.
    #[must_use]
    pub fn planned_stop(&self) -> Option<f32> {
        self.planner.stop_at()
    }

    /// The ego measured against the planner's path: d to its closest (bent) waypoint and the
    /// lateral offset from it. The route's tracking when the planner follows the route.
    #[must_use]
    pub fn planned_tracking(&self) -> Tracking {
        let Some(det) = self.planner.detour() else { return self.tracking };
        let s = self.tracking.s;
        let spacing = self.cfg.waypoint_spacing;
        let len = self.route.length();
        let i = self.tracker.waypoint;
        let d = (i.saturating_sub(1)..(i + 3).min(self.route.waypoints.len()))
            .map(|k| {
                let ws = (k as f32 * spacing).min(len);
                (self.route.waypoints[k] + left_normal(self.route.path.tangent_at(ws)) * det.offset_at(ws)).distance(self.ego.pos)
            })
            .fold(f32::INFINITY, f32::min);
        Tracking { d, s, lateral: self.tracking.lateral - det.offset_at(s) }
    }

    fn update_planner(&mut self) {
        let world = WorldView {
            town: &self.town,
            route: &self.route,
            ego: &self.ego,
            ego_s: self.tracking.s,
            vehicle: &self.cfg.vehicle,
            traffic: &self.traffic,
            parked: &self.parked,
            hazard: self.hazard.as_ref(),
            ego_hold: self.ego_hold,
        };
        self.planner.update(&world);
    }

    /// The last front-camera image (empty without a camera).
    #[must_use]
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// What the network sees of the camera: the last `[env.camera] stack` frames stacked
    /// (`camera::FrameStack`), or the last image when the stack is 1.
    #[must_use]
    pub fn stacked_image(&self) -> &Image {
        self.frames.as_ref().map_or(&self.image, FrameStack::image)
    }

    /// The vector sensor's reading of the current state (`[env.vector]`; `None` without it).
    #[must_use]
    pub fn vector(&self) -> Option<&[f32]> {
        self.cfg.vector.is_some().then_some(self.vector.as_slice())
    }

    /// Reads the vector sensor, when configured.
    fn sense(&mut self) {
        let Some(vc) = &self.cfg.vector else { return };
        let hybrid = self.cfg.variant == Variant::Hybrid;
        let (d, features) = if hybrid { (self.planned_tracking().d, self.path_features()) } else { (0.0, [0.0; PATH_FEATURES]) };
        let (route, detour) = (&self.route, self.planner.detour());
        let point_at = |s: f32| match &detour {
            None => route.path.point_at(s),
            Some(d) => bent_point(route, d, s),
        };
        let path = hybrid.then(|| PathInput {
            d,
            features,
            ego_s: self.tracking.s,
            route_length: route.length(),
            spacing: self.cfg.waypoint_spacing,
            point_at: &point_at,
        });
        let world = World {
            town: &self.town,
            vehicle: &self.cfg.vehicle,
            ego: &self.ego,
            prev_speed: self.prev_speed,
            dt: self.cfg.dt,
            traffic: &self.traffic,
            parked: &self.parked,
            hazard: self.hazard.as_ref(),
            path,
            d0: self.cfg.reward.d0,
        };
        self.sensor.read(vc, &world, &mut self.vector);
    }

    /// Renders the bird's-eye debug view around the ego vehicle.
    #[must_use]
    pub fn birdseye(&mut self, view: &BirdsEye) -> Image {
        self.collect_scene();
        view.render(&self.town, self.ego.pos, self.ego_body(), &self.scene, &self.route, self.tracker.waypoint)
    }

    fn collect_scene(&mut self) {
        self.scene.clear();
        for (i, (body, _)) in self.traffic.bodies().enumerate() {
            self.scene.push(car_box(body, i));
        }
        for (i, body) in self.parked.iter().enumerate() {
            self.scene.push(car_box(*body, i + 3));
        }
        if let Some(h) = &self.hazard {
            self.scene.extend(h.props.iter().enumerate().map(|(i, p)| prop_box(p, i + 5)));
            self.scene.extend(h.walkers.iter().map(|w| walker_box(w.body(), WALKER_HEIGHT)));
        }
    }

    fn render(&mut self) {
        if self.camera.is_none() {
            return;
        }
        self.collect_scene();
        let camera = self.camera.as_mut().expect("checked above");
        camera.render(&self.town, self.ego.pos, self.ego.heading, &self.scene, &mut self.image);
    }

    /// Diagnostics of the last step (or of the reset).
    #[must_use]
    pub fn info(&self) -> &StepInfo {
        &self.last_info
    }

    /// Whether the episode has ended.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// Steps taken since reset.
    #[must_use]
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// The ego vehicle's body.
    #[must_use]
    pub fn ego_body(&self) -> Obb {
        Obb::new(self.ego.pos, self.cfg.vehicle.half_extents(), self.ego.heading)
    }

    /// How many junctions the ego entered this episode without right of way (its connector not
    /// granted by the junction's reservations).
    #[must_use]
    pub fn right_of_way_violations(&self) -> u32 {
        self.right_of_way_violations
    }

    /// The junction connector the ego vehicle holds (may cross), if any.
    #[must_use]
    pub fn ego_hold(&self) -> Option<LaneId> {
        self.ego_hold
    }

    /// The next junction connector on the route ahead of the ego and the route distance to its
    /// entry, if one lies ahead.
    #[must_use]
    pub fn next_connector(&self) -> Option<(LaneId, f32)> {
        let s = self.tracking.s;
        self.route
            .lanes
            .iter()
            .find(|&&(lane, start)| start + 0.5 > s && self.town.is_connector(lane))
            .map(|&(lane, start)| (lane, start - s))
    }

    /// A hash of the whole dynamic state (ego, traffic, route progress): equal hashes after the
    /// same seed and actions show bit-identical trajectories.
    #[must_use]
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv1a64::default();
        let e = &self.ego;
        for x in [e.pos.x, e.pos.y, e.heading, e.speed, e.steer, self.tracking.d, self.tracking.s] {
            h.write_u64(x.to_bits() as u64);
        }
        for c in &self.traffic.cars {
            for x in [c.pos.x, c.pos.y, c.heading, c.speed, c.s] {
                h.write_u64(x.to_bits() as u64);
            }
            h.write_u64(c.lane as u64);
            h.write_u64(c.active as u64);
        }
        for p in &self.parked {
            h.write_u64(p.centre.x.to_bits() as u64);
        }
        if let Some(hz) = &self.hazard {
            hz.hash_into(&mut |x| h.write_u64(x));
        }
        h.finish()
    }

    fn info_now(&self, collision: Option<CollisionKind>, arrived: bool, reward_terms: RewardTerms) -> StepInfo {
        StepInfo {
            d: self.planned_tracking().d,
            l: self.ego.pos.distance(self.route.destination()),
            speed: self.ego.speed,
            collision,
            progress: (self.tracking.s / self.route.length()).clamp(0.0, 1.0),
            arrived,
            reward_terms,
            steps: self.steps,
            hazard: self.hazard.as_ref().map(Hazard::info),
        }
    }

    /// Keeps the ego's junction reservation in step with where it is on its route: hold the
    /// connector it is on, release it once clear, and request the next one when near it.
    fn update_ego_junction(&mut self) {
        let s = self.tracking.s;
        let on_route = self.tracking.lateral.abs() < 3.0;
        let current = self.route.lane_at(s);
        if let Some(h) = self.ego_hold {
            let exit_start = self.route.lanes.iter().skip_while(|&&(l, _)| l != h).nth(1).map_or(f32::INFINITY, |&(_, st)| st);
            if s > exit_start + RELEASE_DISTANCE || !on_route && current != h {
                self.ego_hold = None;
            }
        }
        if on_route && self.town.is_connector(current) && self.ego_hold.is_none() {
            // Entered without a grant: it is there all the same, and traffic must know.
            self.ego_hold = Some(current);
            self.right_of_way_violations += 1;
            self.ego_request = None;
        }
        match self.next_connector() {
            Some((c, dist))
                if on_route
                    && dist - self.cfg.vehicle.length / 2.0 < self.cfg.traffic.idm.request_distance(self.ego.speed)
                    && self.ego_hold != Some(c) =>
            {
                if self.ego_request.is_none_or(|r| r.connector != c) {
                    self.ego_request = Some(EgoRequest { connector: c, since: self.clock });
                }
            }
            _ => self.ego_request = None,
        }
    }

    fn collision(&self, body: &Obb) -> Option<CollisionKind> {
        let (lo, hi) = body.aabb();
        let overlaps = |b: &Obb| {
            let (l2, h2) = b.aabb();
            lo.x <= h2.x && l2.x <= hi.x && lo.y <= h2.y && l2.y <= hi.y && body.intersects(b)
        };
        for (b, parked) in self.traffic.bodies() {
            if overlaps(&b) {
                return Some(if parked { CollisionKind::ParkedCar } else { CollisionKind::Vehicle });
            }
        }
        if self.parked.iter().any(overlaps) {
            return Some(CollisionKind::ParkedCar);
        }
        if let Some(kind) = self.hazard.as_ref().and_then(|h| h.hit(body)) {
            return Some(kind);
        }
        if let Some(kind) = self.town.statics.hit(body) {
            return Some(kind);
        }
        leaves_drivable_area(&self.town.map, body).then_some(CollisionKind::OffRoad)
    }

    /// Parks up to `n` cars in the shoulders of roads that have them, 8 m apart, clear of the
    /// junctions and of the ego's start.
    fn place_parked_cars(&mut self, n: usize, ego_start: Vec2) -> Vec<Obb> {
        let map = &self.town.map;
        let roads: Vec<usize> = (0..map.roads.len()).filter(|&r| map.roads[r].shoulder >= 2.0).collect();
        let mut out: Vec<Obb> = Vec::new();
        if roads.is_empty() {
            return out;
        }
        let half = self.cfg.vehicle.half_extents();
        for _ in 0..n {
            for _try in 0..20 {
                let road = &map.roads[roads[self.rng.random_range(0..roads.len())]];
                let (s0, s1) = (road.cut_start + 8.0, road.centre.length() - road.cut_end - 8.0);
                if s1 <= s0 {
                    continue;
                }
                let st = self.rng.random_range(s0..s1);
                let right = self.rng.random_bool(0.5);
                let tangent = road.centre.tangent_at(st);
                let offset = if right { -(road.right_width() - road.shoulder / 2.0) } else { road.left_width() - road.shoulder / 2.0 };
                let centre = road.centre.point_at(st) + left_normal(tangent) * offset;
                let heading = crate::math::heading_of(if right { tangent } else { -tangent });
                let car = Obb::new(centre, half, heading);
                if centre.distance(ego_start) < 10.0
                    || out.iter().any(|o| o.centre.distance(centre) < 8.0)
                    || self.town.statics.hit(&car).is_some()
                {
                    continue;
                }
                out.push(car);
                break;
            }
        }
        out
    }
}

/// A route point shifted sideways by a detour.
fn bent_point(route: &Route, d: &Detour, s: f32) -> Vec2 {
    route.path.point_at(s) + left_normal(route.path.tangent_at(s)) * d.offset_at(s)
}

/// The stream of an episode's seed that hazards draw from (`HAZ` in ASCII).
const HAZARD_STREAM: u64 = 0x0048_415a;
/// Random routes a hazard episode draws at most to find one with room for its kind.
const HAZARD_ROUTE_TRIES: usize = 40;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expert::Expert;

    /// Hashes of the camera images of an episode driven by the reference driver.
    fn image_hashes(seed: u64) -> Vec<u64> {
        let mut cfg = EnvConfig::default();
        cfg.traffic.vehicles = 30;
        let mut env = Env::new(Town::default_town(), cfg).unwrap();
        env.reset(seed, Scenario::Eval(crate::scenario::EvalRoute::LeftTurn)).unwrap();
        let expert = Expert::default();
        let mut hashes = vec![env.image().hash()];
        for _ in 0..150 {
            let r = env.step(expert.act(&env)).unwrap();
            let img = r.observation.image.expect("camera configured");
            assert_eq!((img.width, img.height, img.channels), (84, 84, 1));
            hashes.push(img.hash());
            if r.terminated || r.truncated {
                break;
            }
        }
        hashes
    }

    #[test]
    fn same_seed_gives_identical_images() {
        let a = image_hashes(7);
        assert!(a.len() > 100, "the episode should last: {} steps", a.len());
        assert_eq!(a, image_hashes(7));
        assert_ne!(a, image_hashes(8), "other traffic should look different");
    }

    #[test]
    fn no_camera_means_no_image() {
        let cfg = EnvConfig { camera: None, ..EnvConfig::default() };
        let mut env = Env::new(Town::default_town(), cfg).unwrap();
        let r = env.step(Action::new(1.0, 0.0, 0.0)).unwrap();
        assert!(r.observation.image.is_none());
    }
}
