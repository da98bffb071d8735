//! Where a run drove, for a picture of it (`actor eval --suite … --trajectories-out`): the ego's
//! position and speed at every step, the route's centre line, and what stood in the way — the
//! hazard's car, props and walkers and the parked cars near the hazard — at the start and at the
//! end. Ground truth from the simulator, rounded to centimetres (a picture needs no more).

use serde::Serialize;
use sim_core::collision::Obb;
use sim_core::env::Env;
use sim_core::hazards::PropKind;
use sim_core::math::Vec2;

use crate::eval::score::RunScore;

/// Parked cars this close to the hazard point are drawn (the car a walker steps out behind).
const PARKED_NEAR_M: f32 = 60.0;
/// At the end, traffic cars this close to the ego are drawn too (what it may have hit).
const TRAFFIC_NEAR_M: f32 = 12.0;

/// A box in the world: centre, half extents, angle (radians).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Body {
    /// `hazard_car`, `cone`, `barrier`, `parked_car` (a hazard's prop), `parked` (on a shoulder),
    /// `walker` (a point: half extents zero) or, at the end only, `traffic` (a moving car near
    /// the ego).
    pub kind: &'static str,
    pub centre: [f32; 2],
    pub half: [f32; 2],
    pub angle: f32,
}

/// One run's trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trajectory {
    pub agent: String,
    pub scenario: &'static str,
    pub seed: u64,
    pub hazard: Option<&'static str>,
    /// The hazard point on the route: `[x, y]` (`null` without a hazard).
    pub hazard_point: Option<[f32; 2]>,
    /// The route's centre line, origin to destination.
    pub route: Vec<[f32; 2]>,
    /// `[x, y, speed m/s]` after the reset and after every step.
    pub ego: Vec<[f32; 3]>,
    pub bodies_start: Vec<Body>,
    /// The same at the end, and the traffic cars within 12 m of the ego then.
    pub bodies_end: Vec<Body>,
    /// How the run ended, as the report's infractions name it, and its driving score.
    pub infractions: Vec<&'static str>,
    pub driving_score: f64,
}

fn cm(x: f32) -> f32 {
    (x * 100.0).round() / 100.0
}

fn point(p: Vec2) -> [f32; 2] {
    [cm(p.x), cm(p.y)]
}

fn body(kind: &'static str, b: &Obb) -> Body {
    Body { kind, centre: point(b.centre), half: point(b.half), angle: cm(b.angle) }
}

/// What stands in the way now: the hazard's objects, and the parked cars near its point.
fn bodies(env: &Env) -> Vec<Body> {
    let mut out = Vec::new();
    let Some(h) = env.hazard.as_ref() else { return out };
    if let Some(i) = h.car.filter(|&i| i < env.traffic.cars.len()) {
        out.push(body("hazard_car", &env.traffic.body(i)));
    }
    for p in &h.props {
        let kind = match p.kind {
            PropKind::Cone => "cone",
            PropKind::Barrier => "barrier",
            PropKind::ParkedCar => "parked_car",
        };
        out.push(body(kind, &p.body));
    }
    for w in &h.walkers {
        out.push(Body { kind: "walker", centre: point(w.pos), half: [0.0, 0.0], angle: 0.0 });
    }
    let at = env.route.path.point_at(h.s);
    out.extend(env.parked.iter().filter(|b| b.centre.distance(at) <= PARKED_NEAR_M).map(|b| body("parked", b)));
    out
}

/// The traffic cars near the ego (the hazard's own car left out: `bodies` has it).
fn traffic_near_ego(env: &Env) -> impl Iterator<Item = Body> + '_ {
    let own = env.hazard.as_ref().and_then(|h| h.car);
    (0..env.traffic.cars.len())
        .filter(move |&i| Some(i) != own)
        .map(|i| env.traffic.body(i))
        .filter(|b| b.centre.distance(env.ego.pos) <= TRAFFIC_NEAR_M)
        .map(|b| body("traffic", &b))
}

/// Follows one run step by step.
#[derive(Debug, Clone, Default)]
pub struct TrajectoryRecorder {
    ego: Vec<[f32; 3]>,
    start: Vec<Body>,
}

impl TrajectoryRecorder {
    /// Records the state after a step (and after the reset, before the first one).
    pub fn record(&mut self, env: &Env) {
        if self.ego.is_empty() {
            self.start = bodies(env);
        }
        let p = point(env.ego.pos);
        self.ego.push([p[0], p[1], cm(env.ego.speed)]);
    }

    /// The trajectory of `run`, which has ended in `env`.
    #[must_use]
    pub fn finish(self, env: &Env, agent: &str, scenario: &'static str, run: &RunScore) -> Trajectory {
        Trajectory {
            agent: agent.to_owned(),
            scenario,
            seed: run.seed,
            hazard: env.hazard.as_ref().map(|h| h.kind.name()),
            hazard_point: env.hazard.as_ref().map(|h| point(env.route.path.point_at(h.s))),
            route: env.route.path.points().iter().map(|&p| point(p)).collect(),
            ego: self.ego,
            bodies_start: self.start,
            bodies_end: bodies(env).into_iter().chain(traffic_near_ego(env)).collect(),
            infractions: run.infractions.iter().map(|i| i.name()).collect(),
            driving_score: run.driving_score,
        }
    }
}
