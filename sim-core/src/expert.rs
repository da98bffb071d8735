//! The model-based reference driver: pure-pursuit steering on the A* route, speed control toward
//! v0 limited by curvature, and yielding to vehicles ahead and to junction right of way. It is
//! the planner followed by a classical controller — the baseline of evaluations.
//!
//! It follows the environment's planner (`[env] planner`): the A* route, or the route bent around
//! obstacles by `astar+avoid`, stopping where that planner finds no way round. Its knowledge of
//! other road users is its car-following's: the cars in its corridor. With `sees_hazards` (the
//! `model-based-avoid` baseline) it also brakes for walkers and hazard cars whose next three
//! seconds, at their current velocity, enter its corridor.

use crate::env::Env;
use crate::math::{Vec2, atan, atan2, cross, heading_of, sin, wrap_angle};
use crate::traffic::IdmParams;
use crate::vehicle::Action;

/// Lateral acceleration accepted in curves, m/s².
const LATERAL_ACCEL: f32 = 3.0;
/// How far ahead along the route speed limits and obstacles are looked for, metres.
const LOOKAHEAD: f32 = 60.0;
/// Half-width of the corridor along the route in which another vehicle counts as ahead, metres.
const CORRIDOR: f32 = 2.6;

/// The pure-pursuit lookahead at speed `v` (m/s), metres. Free to retune: the observation's
/// path features have their own, frozen preview distance (`path_features::near_preview`).
#[must_use]
pub fn lookahead(v: f32) -> f32 {
    (0.5 * v + 3.0).clamp(4.0, 12.0)
}

/// The reference driver. Stateless: it reads the environment's ground truth each step.
#[derive(Debug, Clone)]
pub struct Expert {
    /// Car-following behaviour toward obstacles ahead.
    pub idm: IdmParams,
    /// Whether it perceives the hazard's walkers and cars and brakes for their predicted paths.
    pub sees_hazards: bool,
}

impl Default for Expert {
    fn default() -> Self {
        Self { idm: IdmParams { accel: 2.5, comfort_decel: 3.0, max_decel: 8.0, min_gap: 3.0, headway: 1.0 }, sees_hazards: false }
    }
}

/// Seconds ahead a perceived walker's or car's path is predicted.
const PREDICTION: f32 = 3.0;
/// Speed held while on or near a detour, m/s.
const DETOUR_SPEED: f32 = 8.0;

impl Expert {
    /// The `model-based-avoid` driver: perceives hazards (drive it with the `astar+avoid` planner).
    #[must_use]
    pub fn avoiding() -> Self {
        Self { sees_hazards: true, ..Self::default() }
    }

    /// The action for the environment's current state.
    #[must_use]
    pub fn act(&self, env: &Env) -> Action {
        let p = &env.cfg.vehicle;
        let ego = &env.ego;
        let route = &env.route;
        let s = env.tracking.s;
        let v = ego.speed;

        // Pure pursuit from the rear axle toward a point ahead on the route.
        let lookahead = lookahead(v);
        let rear = ego.pos - ego.forward() * (p.wheelbase / 2.0);
        let target = env.planned_point(s + lookahead);
        let detour = env.detour();
        let to_target = target - rear;
        let alpha = wrap_angle(heading_of(to_target) - ego.heading);
        let wheel = atan(2.0 * p.wheelbase * sin(alpha) / to_target.length().max(1.0));
        let steer = (-wheel / p.steer_limit(v)).clamp(-1.0, 1.0);

        // Speed: v0, curves ahead, obstacles ahead, junction right of way.
        let v0 = env.cfg.reward.v0();
        let mut v_des = v0;
        let mut x = 0.0;
        while x < LOOKAHEAD {
            let kappa = curvature(&route.path, s + x);
            if kappa > 1e-4 {
                let v_curve = (LATERAL_ACCEL / kappa).sqrt();
                v_des = v_des.min((v_curve * v_curve + 2.0 * self.idm.comfort_decel * (x - 3.0).max(0.0)).sqrt());
            }
            x += 2.0;
        }
        let mut leader: Option<(f32, f32)> = None;
        let mut consider = |gap: f32, speed: f32| {
            if leader.is_none_or(|(g, _)| gap < g) {
                leader = Some((gap, speed));
            }
        };
        let half = p.length / 2.0;
        for (i, c) in env.traffic.cars.iter().enumerate() {
            if !c.active || c.pos.distance_squared(ego.pos) > LOOKAHEAD * LOOKAHEAD {
                continue;
            }
            let proj = route.path.project_range(c.pos, route.path.segment_at(s), route.path.segment_at(s + LOOKAHEAD) + 1);
            let body = env.traffic.body(i);
            // On a detour the corridor is the body's width and a margin: the planner has checked
            // that the path clears what it passes.
            let (off, corridor) = detour
                .map_or((proj.distance, CORRIDOR), |d| ((proj.lateral - d.offset_at(proj.s)).abs(), p.width / 2.0 + body.half.y + 0.25));
            if proj.s > s && off < corridor {
                // Speed along the route (a crossing car counts as stopped).
                let along = c.speed
                    * route.path.tangent_at(proj.s).dot(Vec2::new(crate::math::cos(c.heading), crate::math::sin(c.heading))).max(0.0);
                consider(proj.s - s - half - body.half.x, along);
            }
        }
        if let Some(stop) = env.planned_stop() {
            consider(stop - s, 0.0);
        }
        if let Some(d) = detour
            && d.end > s
            && d.start < s + 30.0
        {
            v_des = v_des.min(DETOUR_SPEED);
        }
        if self.sees_hazards
            && let Some(h) = &env.hazard
        {
            let window = (route.path.segment_at(s), route.path.segment_at(s + LOOKAHEAD) + 1);
            let mut movers: Vec<(Vec2, Vec2, f32, bool)> = h.walkers.iter().map(|w| (w.pos, w.velocity(), 0.6, false)).collect();
            if let Some(i) = h.car
                && env.traffic.cars[i].active
            {
                let c = &env.traffic.cars[i];
                movers.push((c.pos, crate::math::dir(c.heading) * c.speed, p.width / 2.0, true));
            }
            for (pos, vel, radius, car) in movers {
                let mut t = 0.0;
                while t <= PREDICTION {
                    let q = route.path.project_range(pos + vel * t, window.0, window.1);
                    let off = (q.lateral - detour.map_or(0.0, |d| d.offset_at(q.s))).abs();
                    if q.s > s && q.s < s + LOOKAHEAD && off < p.width / 2.0 + radius + 0.4 {
                        // A car already in the corridor is followed as a car; one coming into it,
                        // and any walker, is stopped for.
                        if !(car && t == 0.0) {
                            consider(q.s - s - half - radius, 0.0);
                        }
                        break;
                    }
                    t += 0.25;
                }
            }
        }
        if let Some((conn, dist)) = env.next_connector()
            && env.ego_hold() != Some(conn)
        {
            // Stop at the line until the junction lets us in.
            consider(dist - half - 0.5, 0.0);
        }
        let dist_to_goal = route.length() - s;
        v_des = v_des.min((2.0 * self.idm.comfort_decel * dist_to_goal).sqrt() + 3.0);
        let a = self.idm.accel(v, v_des, leader);

        // Acceleration to pedals, inverting the vehicle model.
        let drive_gain = p.max_accel * (1.0 - v / p.max_speed).max(0.05);
        let coast = if v > 0.0 { p.coast_decel } else { 0.0 };
        let (throttle, brake) = if a + coast >= 0.0 { ((a + coast) / drive_gain, 0.0) } else { (0.0, (-(a + coast)) / p.max_brake) };
        Action::new(throttle, brake, steer).clamped()
    }
}

/// Unsigned curvature of a polyline around arc length `s`, from the turn over ±2 m.
fn curvature(path: &crate::polyline::Polyline, s: f32) -> f32 {
    let (a, b, c) = (path.point_at(s - 2.0), path.point_at(s), path.point_at(s + 2.0));
    let (u, w) = (b - a, c - b);
    let len = u.length() + w.length();
    if len < 1.0 {
        return 0.0;
    }
    atan2(cross(u, w), u.dot(w)).abs() / (0.5 * len)
}
