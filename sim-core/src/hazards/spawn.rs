//! Where a hazard goes: a stretch of one road lane of the ego's route at a seeded distance ahead,
//! never at the start (inside the ego) nor off the route; and the placing of its actors there.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::config::{HazardsConfig, Range};
use super::cut_in;
use super::kind::HazardKind;
use super::runner;
use super::walker::Walker;
use super::{Hazard, Prop, PropKind, Script};
use crate::collision::Obb;
use crate::map::{LaneId, LaneKind};
use crate::math::{Vec2, left_normal};
use crate::route::Route;
use crate::town::Town;
use crate::traffic::Traffic;

/// No hazard stands closer to the route's start than this, metres (the ego is 4.5 m long).
pub const MIN_START_DISTANCE: f32 = 15.0;
/// Room kept between a lane's start and a hazard, metres: a junction lets a car onto a lane only
/// when its entry has room.
const LANE_ENTRY_ROOM: f32 = 15.0;
/// Road kept after an obstacle to pass, for the way back into the lane, metres.
const RETURN_ROOM: f32 = 14.0;
/// Room kept after a hazard before the destination, metres.
const ROOM_AFTER: f32 = 20.0;

/// How much route a kind needs: before its point (from the start of its lane stretch) and after.
fn needs(kind: HazardKind, cfg: &HazardsConfig) -> (f32, f32) {
    match kind {
        // Obstacles to pass leave room on their lane to return to it before the next junction
        // (a car out of its lane at a junction's mouth blocks the traffic that would let it in).
        HazardKind::StalledCar => (0.0, 6.0 + RETURN_ROOM),
        HazardKind::PedestrianCrossing => (8.0, 2.0),
        HazardKind::Construction => (0.0, cfg.closure_length.max + 2.0 + RETURN_ROOM),
        // The leader drives 25 m of the lane before it brakes.
        HazardKind::HardBrake => (27.0, 5.0),
        // The car starts 25 m before the point and times its speed so that the ego reaches it
        // near there (`cut_in.rs`).
        HazardKind::CutIn => (27.0, 40.0),
        HazardKind::OppositeOvertaker => (0.0, 45.0),
        // Placed at a junction instead (`runner.rs`).
        HazardKind::JunctionRunner => (0.0, 0.0),
    }
}

/// The route's stretches on one road lane: (lane, first s, last s).
fn road_stretches<'a>(town: &'a Town, route: &'a Route) -> impl Iterator<Item = (LaneId, f32, f32)> + 'a {
    route.lanes.iter().enumerate().filter_map(move |(i, &(lane, start))| {
        let end = route.lanes.get(i + 1).map_or(route.length(), |&(_, s)| s);
        matches!(town.map.lanes[lane].kind, LaneKind::Road { .. }).then_some((lane, start, end))
    })
}

/// Whether the lane suits the kind (an adjacent lane to cut in from, an opposite lane to come
/// from, a shoulder to stand on).
fn lane_suits(town: &Town, kind: HazardKind, lane: LaneId) -> bool {
    let l = &town.map.lanes[lane];
    let LaneKind::Road { road, index, .. } = l.kind else { return false };
    let road = &town.map.roads[road];
    match kind {
        HazardKind::CutIn => l.left.is_some() || l.right.is_some(),
        HazardKind::OppositeOvertaker => {
            index == 0 && !road.backward.is_empty() && !road.forward.is_empty() && l.right.is_none() && road.shoulder >= 2.0
        }
        _ => true,
    }
}

/// The interval of hazard points `s` the route offers for `kind` (closest to the distance
/// range), with its lane; `None` if the route has no room.
#[must_use]
pub fn feasible(kind: HazardKind, cfg: &HazardsConfig, town: &Town, route: &Route) -> Option<(LaneId, Range)> {
    if kind == HazardKind::JunctionRunner {
        return runner::find(cfg, town, route).map(|c| (c.approach, Range::new(c.s, c.s)));
    }
    let (before, after) = needs(kind, cfg);
    let mut best: Option<(f32, LaneId, Range)> = None;
    for (lane, a, b) in road_stretches(town, route) {
        if !lane_suits(town, kind, lane) {
            continue;
        }
        let lo = (a + before + LANE_ENTRY_ROOM).max(MIN_START_DISTANCE).max(if kind == HazardKind::HardBrake { 40.0 } else { 0.0 });
        let hi = (b - after - 1.0).min(route.length() - ROOM_AFTER);
        if hi < lo {
            continue;
        }
        // Distance from the wanted range to this interval (0 if they overlap).
        let miss = (lo - cfg.distance.max).max(cfg.distance.min - hi).max(0.0);
        if best.as_ref().is_none_or(|&(m, _, _)| miss < m) {
            best = Some((miss, lane, Range::new(lo, hi)));
        }
    }
    best.map(|(_, lane, r)| (lane, r))
}

/// A point of the route at `s`, `lateral` metres to its left.
fn at(route: &Route, s: f32, lateral: f32) -> Vec2 {
    route.path.point_at(s) + left_normal(route.path.tangent_at(s)) * lateral
}

fn draw(rng: &mut ChaCha8Rng, r: Range) -> f32 {
    if r.max > r.min { rng.random_range(r.min..=r.max) } else { r.min }
}

/// Cone half-side and height, metres.
const CONE_HALF: f32 = 0.2;
const CONE_HEIGHT: f32 = 0.75;
/// The occluding parked car's height (a car's, as the camera draws cars), metres.
const PARKED_CAR_HEIGHT: f32 = 1.5;

/// Places a hazard of `kind` on `route` (with its actors in `traffic`), or `None` if the route
/// has no room for it.
pub fn place(
    kind: HazardKind,
    cfg: &HazardsConfig,
    town: &Town,
    route: &Route,
    traffic: &mut Traffic,
    rng: &mut ChaCha8Rng,
) -> Option<Hazard> {
    let (lane, range) = feasible(kind, cfg, town, route)?;
    let s = draw(rng, cfg.distance).clamp(range.min, range.max);
    let l = &town.map.lanes[lane];
    let w = l.width;
    let heading = route.path.heading_at(s);
    let lane_s = |p: Vec2| l.path.project(p).s;
    let mut hazard = Hazard { kind, s, walkers: Vec::new(), props: Vec::new(), car: None, script: Script::Static, triggered: false };
    match kind {
        HazardKind::StalledCar => {
            traffic.add_parked_on_lane(town, lane, lane_s(route.path.point_at(s)));
            hazard.car = Some(traffic.cars.len() - 1);
        }
        HazardKind::Construction => {
            let length = draw(rng, cfg.closure_length);
            // A barrier across the lane, a taper of cones from the right edge to the left, then a
            // line of cones along the left edge to the closure's end.
            let barrier = Obb::new(at(route, s, 0.0), Vec2::new(0.25, w / 2.0 - 0.35), heading);
            hazard.props.push(Prop { body: barrier, height: 1.0, kind: PropKind::Barrier });
            hazard.script = Script::Closure { lane, barrier: lane_s(barrier.centre) };
            for k in 0..5 {
                let t = k as f32 / 4.0;
                let p = at(route, s - 4.0 + 4.0 * t, -w / 2.0 + 0.25 + t * (w - 0.5));
                hazard.props.push(Prop { body: Obb::new(p, Vec2::splat(CONE_HALF), heading), height: CONE_HEIGHT, kind: PropKind::Cone });
            }
            let mut x = 3.0;
            while x <= length {
                let p = at(route, s + x, w / 2.0 - 0.25);
                hazard.props.push(Prop { body: Obb::new(p, Vec2::splat(CONE_HALF), heading), height: CONE_HEIGHT, kind: PropKind::Cone });
                x += 3.0;
            }
        }
        HazardKind::PedestrianCrossing => {
            let LaneKind::Road { road, .. } = l.kind else { return None };
            let road = &town.map.roads[road];
            let outermost = l.right.is_none();
            let shoulder = if outermost { road.shoulder } else { 0.0 };
            // Stand in the shoulder (or at the sidewalk's edge) just beyond a parked car that hides
            // the walker from the approaching ego.
            let stand = if shoulder >= 2.0 { -(w / 2.0 + shoulder / 2.0) } else { -(w / 2.0 + shoulder + 0.6) };
            if shoulder >= 2.0 {
                let occluder = Obb::new(at(route, s - 5.5, stand), traffic.params.half_extents(), heading);
                hazard.props.push(Prop { body: occluder, height: PARKED_CAR_HEIGHT, kind: PropKind::ParkedCar });
            }
            let across = road.left_width() + road.right_width();
            let speed = draw(rng, cfg.walker_speed);
            hazard.walkers.push(Walker {
                pos: at(route, s, stand),
                direction: left_normal(route.path.tangent_at(s)),
                speed,
                distance_left: across + 1.5,
                walking: false,
            });
            hazard.script = Script::Crossing { trigger_time: draw(rng, cfg.trigger_time) };
        }
        HazardKind::HardBrake => {
            let start = s - 25.0;
            let speed = l.speed_limit * 0.8;
            let i = traffic.add_driving_on_lane(town, lane, lane_s(route.path.point_at(start)), speed, next_on_route(route, lane));
            traffic.cars[i].forced_accel = Some(0.0);
            hazard.car = Some(i);
            hazard.script = Script::HardBrake { stop_time: draw(rng, cfg.stop_time), stopped_for: 0.0, released: false };
        }
        HazardKind::CutIn => {
            let from = l.left.or(l.right)?;
            let side = if l.left == Some(from) { 1.0 } else { -1.0 };
            let p = at(route, s - 25.0, side * w);
            let fl = &town.map.lanes[from];
            let i = traffic.add_driving_on_lane(town, from, fl.path.project(p).s, cut_in::MIN_SPEED, fl.successors.first().copied());
            traffic.cars[i].forced_accel = Some(0.0);
            hazard.car = Some(i);
            hazard.script = Script::CutIn { lane, gap: draw(rng, cfg.cut_in_gap), phase: 0, side };
        }
        HazardKind::OppositeOvertaker => {
            let LaneKind::Road { road, forward, .. } = l.kind else { return None };
            let road = &town.map.roads[road];
            let opposite = if forward { road.backward[0] } else { road.forward[0] };
            let ol = &town.map.lanes[opposite];
            let p = at(route, s + 40.0, w);
            let i = traffic.add_driving_on_lane(town, opposite, ol.path.project(p).s, ol.speed_limit * 0.8, ol.successors.first().copied());
            traffic.cars[i].forced_accel = Some(0.0);
            hazard.car = Some(i);
            hazard.script = Script::Overtake { width: w, out_for: 0.0, phase: 0 };
        }
        HazardKind::JunctionRunner => {
            let c = runner::find(cfg, town, route)?;
            let approach = &town.map.lanes[c.approach];
            let start = (approach.path.length() - runner::RUNNER_APPROACH).max(5.0);
            let i = traffic.add_driving_on_lane(town, c.approach, start, 0.0, Some(c.connector));
            traffic.cars[i].forced_accel = Some(0.0);
            // The runner's lane ahead of it and its connector empty: nothing to stop it there.
            let ahead: Vec<usize> = (0..traffic.cars.len())
                .filter(|&j| {
                    let o = &traffic.cars[j];
                    j != i && o.active && (o.lane == c.connector || o.lane == c.approach && o.s > start - 8.0)
                })
                .collect();
            for j in ahead {
                traffic.remove(j);
            }
            hazard.s = c.s;
            hazard.car = Some(i);
            hazard.script = Script::JunctionRunner {
                approach: c.approach,
                connector: c.connector,
                along: c.along,
                speed: draw(rng, cfg.runner_speed),
                phase: 0,
            };
        }
    }
    clear_around(route, traffic, &hazard);
    Some(hazard)
}

/// The lane the route takes after `lane`.
fn next_on_route(route: &Route, lane: LaneId) -> Option<LaneId> {
    route.lanes.iter().skip_while(|&&(l, _)| l != lane).nth(1).map(|&(l, _)| l)
}

/// Takes off the map the traffic that would make the hazard another one: cars on the ego's lane
/// between the start and beyond the hazard, and any car within 15 m of it.
fn clear_around(route: &Route, traffic: &mut Traffic, hazard: &Hazard) {
    let point = route.path.point_at(hazard.s);
    let upto = hazard.s + 40.0;
    let mut remove = Vec::new();
    for (i, c) in traffic.cars.iter().enumerate() {
        if !c.active || Some(i) == hazard.car {
            continue;
        }
        let p = route.path.project(c.pos);
        let along = route.path.tangent_at(p.s).dot(crate::math::dir(c.heading)) > 0.5;
        if c.pos.distance(point) < 15.0 || p.s < upto && p.distance < 2.5 && along {
            remove.push(i);
        }
    }
    for i in remove {
        traffic.remove(i);
    }
}
