//! `astar+avoid`: the A* route bent around what blocks it. Each step, before a detour is under
//! way, it gathers the obstacles ahead (a hazard's props and stalled car, parked cars, an oncoming
//! car in the ego's lane), and if any stands in the ego's corridor it tries lateral offsets, the
//! smallest first, left before right: an offset is taken if the ego's body along the detour stays
//! clear of every obstacle, on drivable ground and off the buildings, and if no car is coming in
//! the lane it borrows before the ego is back (or moving in it, on a lane change). When none is
//! clear it asks to stop before the obstacle, and tries again next step. A detour under way is
//! kept until its end.

use super::{Detour, Planner, WorldView};
use crate::collision::Obb;
use crate::math::{Vec2, dir, left_normal};

/// How far ahead obstacles are looked for, metres.
const LOOKAHEAD: f32 = 60.0;
/// Clearance kept on each side of the ego's body, metres.
const MARGIN: f32 = 0.35;
/// Offsets tried, metres (each to the left, then to the right).
const OFFSETS: [f32; 15] = [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5, 2.75, 3.0, 3.25, 3.5, 3.75, 4.0];
/// A stopped car this close behind an obstacle is queued behind it, metres.
const QUEUE_GAP: f32 = 10.0;
/// Seconds of margin an oncoming car must leave after the ego is back in its lane.
const GAP_MARGIN: f32 = 2.0;

/// An obstacle as seen along the route: its arc-length and lateral extents.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Extent {
    s0: f32,
    s1: f32,
    l0: f32,
    l1: f32,
    /// The edge of drivable ground, not a thing: worth a detour, not a stop.
    curb: bool,
}

/// The avoiding planner's state: the detour under way or proposed, where to stop, and the
/// stretches where the route itself leaves drivable ground (found once per route).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AvoidPlanner {
    detour: Option<Detour>,
    stop_at: Option<f32>,
    curbs: Option<Vec<Extent>>,
}

impl Planner for AvoidPlanner {
    fn update(&mut self, w: &WorldView<'_>) {
        let curbs = self.curbs.get_or_insert_with(|| curbs(w));
        let mut obstacles = obstacles(w);
        obstacles.extend(curbs.iter().copied().filter(|e| e.s1 > w.ego_s - 3.0 && e.s0 < w.ego_s + LOOKAHEAD));
        let hw = w.vehicle.width / 2.0 + MARGIN;
        let half_len = w.vehicle.length / 2.0;
        if let Some(d) = self.detour
            && w.ego_s >= d.start
            && w.ego_s < d.end
        {
            // Under way: keep it, but come back early once nothing is left to pass in the lane.
            self.stop_at = None;
            let passing = obstacles.iter().any(|e| e.l1 > -hw - 1.0 && e.l0 < hw + 1.0 && e.s1 + half_len > w.ego_s && e.s0 < d.full_to);
            if !passing && w.ego_s > d.full_from && w.ego_s < d.full_to {
                let ramp = d.end - d.full_to;
                self.detour = Some(Detour { full_to: w.ego_s, end: w.ego_s + ramp, ..d });
            }
            return;
        }
        self.detour = None;
        self.stop_at = None;
        let mut blocking: Vec<Extent> = obstacles.iter().copied().filter(|e| e.l1 > -hw && e.l0 < hw && e.s1 > w.ego_s).collect();
        if blocking.is_empty() {
            return;
        }
        blocking.sort_by(|a, b| a.s0.total_cmp(&b.s0));
        // The cluster: the first blocker and whatever near the lane follows it closely (the cones
        // along a closure's edge block no offset of 0 but do the return).
        let (sa, mut sb) = (blocking[0].s0, blocking[0].s1);
        let mut near: Vec<Extent> = obstacles.iter().copied().filter(|e| e.l1 > -hw - 1.0 && e.l0 < hw + 1.0).collect();
        near.sort_by(|a, b| a.s0.total_cmp(&b.s0));
        for e in &near {
            if e.s0 >= sa && e.s0 < sb + 10.0 {
                sb = sb.max(e.s1);
            }
        }
        // Stopped before it with room to pull out from a standstill.
        if !blocking[0].curb {
            self.stop_at = Some(sa - half_len - STOP_ROOM);
        }
        let v = w.ego.speed;
        let ramp = (8.0 + v).clamp(10.0, 18.0);
        let full_from = sa - half_len - 1.0;
        let start = (full_from - ramp).max(w.ego_s + 0.5);
        if full_from - start < if v < 1.0 { MIN_RAMP_STANDING } else { MIN_RAMP } {
            return;
        }
        let full_to = sb + half_len + 1.0;
        let Some((start, end)) = between_junctions(w, start, full_from, full_to, full_to + ramp) else { return };
        // Round a curb the ego keeps inside its road: only a car beside it matters, with a hand's
        // width between them; round a thing it borrows the lane beside, with a margin.
        let reach = if blocking[0].curb { w.vehicle.width / 2.0 + 0.15 } else { hw + 0.3 };
        for o in OFFSETS.iter().flat_map(|&o| [o, -o]) {
            let d = Detour { start, full_from, full_to, end, offset: o };
            if clear_of(&obstacles, &d, hw, half_len) && drivable(w, &d) && gap_ok(w, &d, reach) {
                self.detour = Some(d);
                self.stop_at = None;
                return;
            }
        }
    }

    fn detour(&self) -> Option<Detour> {
        self.detour
    }

    fn stop_at(&self) -> Option<f32> {
        self.stop_at
    }
}

/// The extents along the route of the obstacles ahead.
fn obstacles(w: &WorldView<'_>) -> Vec<Extent> {
    let path = &w.route.path;
    let (first, last) = (path.segment_at(w.ego_s - 5.0), path.segment_at(w.ego_s + LOOKAHEAD) + 1);
    let extent = |b: &Obb| -> Option<Extent> {
        if b.centre.distance_squared(w.ego.pos) > (LOOKAHEAD + 10.0) * (LOOKAHEAD + 10.0) {
            return None;
        }
        let mut e = Extent { s0: f32::INFINITY, s1: f32::NEG_INFINITY, l0: f32::INFINITY, l1: f32::NEG_INFINITY, curb: false };
        for c in b.corners() {
            let p = path.project_range(c, first, last);
            if p.distance > 15.0 {
                return None;
            }
            (e.s0, e.s1, e.l0, e.l1) = (e.s0.min(p.s), e.s1.max(p.s), e.l0.min(p.lateral), e.l1.max(p.lateral));
        }
        (e.s1 > w.ego_s - 3.0).then_some(e)
    };
    let mut out: Vec<Extent> = Vec::new();
    if let Some(h) = w.hazard {
        out.extend(h.props.iter().filter_map(|p| extent(&p.body)));
    }
    out.extend(w.parked.iter().filter_map(extent));
    out.extend(
        (0..w.traffic.cars.len())
            .filter(|&i| w.traffic.cars[i].active && w.traffic.cars[i].parked)
            .filter_map(|i| extent(&w.traffic.body(i))),
    );
    // Cars standing still in the route's lane right behind an obstacle are queued behind it: part
    // of the obstacle (a few passes, for a queue of several).
    let mut queued = vec![false; w.traffic.cars.len()];
    for _ in 0..3 {
        for (i, c) in w.traffic.cars.iter().enumerate() {
            if !c.active || c.parked || c.speed > 0.3 || queued[i] {
                continue;
            }
            let Some(e) = extent(&w.traffic.body(i)) else { continue };
            if e.l1 < -1.0 || e.l0 > 1.0 {
                continue;
            }
            if out.iter().any(|o| o.s0 > e.s1 - 0.5 && o.s0 < e.s1 + QUEUE_GAP && o.l1 > e.l0 && o.l0 < e.l1) {
                queued[i] = true;
                out.push(e);
            }
        }
    }
    for (i, c) in w.traffic.cars.iter().enumerate() {
        if !c.active || c.parked || queued[i] {
            continue;
        }
        // An oncoming car in the ego's lane sweeps the route between it and the ego (on a road:
        // a car turning across a junction ahead points against the route only for a moment).
        if w.town.is_connector(c.lane) {
            continue;
        }
        let p = path.project_range(c.pos, first, last);
        let oncoming = path.tangent_at(p.s).dot(dir(c.heading)) < -0.5;
        if oncoming && p.s > w.ego_s && p.lateral.abs() < w.vehicle.width && p.distance < 4.0 {
            let half = w.traffic.params.width / 2.0;
            out.push(Extent { s0: w.ego_s + 12.0, s1: p.s + 5.0, l0: p.lateral - half, l1: p.lateral + half, curb: false });
        }
    }
    out
}

/// How far before an obstacle it stops when no way round is clear, metres (front to obstacle).
const STOP_ROOM: f32 = 6.5;
/// Shortest ramp out at speed and from a standstill, metres.
const MIN_RAMP: f32 = 6.0;
const MIN_RAMP_STANDING: f32 = 4.5;
/// Shortest return ramp, metres.
const MIN_RETURN: f32 = 5.0;

/// Where a detour may start and end (at `start` and `end` or within) so that the ego is in its
/// lane at the stop line of every junction it holds no right to cross, for a car standing out of
/// its lane at a junction's mouth blocks the traffic that would let it in: it pulls out after
/// such a junction, or is back before it. `None` if the detour would have to run through one.
fn between_junctions(w: &WorldView<'_>, start: f32, full_from: f32, full_to: f32, end: f32) -> Option<(f32, f32)> {
    let (mut start, mut end) = (start, end);
    for (i, &(lane, entry)) in w.route.lanes.iter().enumerate() {
        let exit = w.route.lanes.get(i + 1).map_or(w.route.length(), |&(_, s)| s);
        if !w.town.is_connector(lane) || exit <= start || w.ego_hold == Some(lane) {
            continue;
        }
        if exit + 0.5 <= full_from - MIN_RAMP {
            start = start.max(exit + 0.5);
        } else if entry >= full_to + MIN_RETURN {
            end = end.min(entry - 0.5);
        } else {
            return None;
        }
    }
    Some((start, end))
}

/// The stretches where the ego's body on the route itself would leave drivable ground (a turn
/// drawn tighter than its surface), as obstacles on the side it would leave by.
fn curbs(w: &WorldView<'_>) -> Vec<Extent> {
    let path = &w.route.path;
    let half = w.vehicle.half_extents() + Vec2::splat(0.15);
    let mut out = Vec::new();
    let mut s = 0.0;
    while s <= w.route.length() {
        let t = path.tangent_at(s);
        let body = Obb::new(path.point_at(s), half, crate::math::heading_of(t));
        if body.corners().iter().any(|&c| !w.town.map.is_drivable(c)) {
            // How far drivable ground reaches on each side of the route here.
            let reach = |side: f32| {
                let mut l = 0.0;
                while l < 4.0 && w.town.map.is_drivable(path.point_at(s) + left_normal(t) * (side * (l + 0.25))) {
                    l += 0.25;
                }
                l
            };
            let (right, left) = (reach(-1.0), reach(1.0));
            if right < half.y {
                out.push(Extent { s0: s - 0.75, s1: s + 0.75, l0: -right - 3.0, l1: -right, curb: true });
            }
            if left < half.y {
                out.push(Extent { s0: s - 0.75, s1: s + 0.75, l0: left, l1: left + 3.0, curb: true });
            }
        }
        s += 1.0;
    }
    out
}

/// Whether the ego's body along the detour keeps clear of every obstacle.
fn clear_of(obstacles: &[Extent], d: &Detour, hw: f32, half_len: f32) -> bool {
    obstacles.iter().all(|e| {
        let mut s = e.s0 - half_len;
        while s <= e.s1 + half_len {
            let o = d.offset_at(s);
            if e.l1 > o - hw && e.l0 < o + hw {
                return false;
            }
            s += 0.5;
        }
        true
    })
}

/// Whether the ego's body along the detour stays on drivable ground and off the buildings.
fn drivable(w: &WorldView<'_>, d: &Detour) -> bool {
    let half = w.vehicle.half_extents() + Vec2::splat(0.15);
    let mut s = d.start;
    while s <= d.end {
        let t = w.route.path.tangent_at(s);
        let centre = w.route.path.point_at(s) + left_normal(t) * d.offset_at(s);
        let body = Obb::new(centre, half, crate::math::heading_of(t));
        if body.corners().iter().any(|&c| !w.town.map.is_drivable(c)) || w.town.statics.hit(&body).is_some() {
            return false;
        }
        s += 1.5;
    }
    true
}

/// Whether the lane the detour borrows is free long enough: no oncoming car reaches the detour
/// before the ego is back (with a margin), and no car moves along it beside the ego. A car
/// counts when its centre line comes within `reach` of the ego's side (plus its own half-width).
fn gap_ok(w: &WorldView<'_>, d: &Detour, reach: f32) -> bool {
    let path = &w.route.path;
    let (first, last) = (path.segment_at(w.ego_s - 20.0), path.segment_at(d.end + 80.0) + 1);
    let ego_time = (d.end - w.ego_s) / w.ego.speed.max(6.0);
    let half = w.traffic.params.width / 2.0;
    w.traffic.cars.iter().all(|c| {
        if !c.active || c.parked {
            return true;
        }
        let p = path.project_range(c.pos, first, last);
        if p.distance > 8.0 || (p.lateral - d.offset).abs() > reach + half {
            return true;
        }
        if path.tangent_at(p.s).dot(dir(c.heading)) < -0.5 {
            // Oncoming: behind the ego already, or arriving after the ego is back.
            p.s < w.ego_s - 3.0 || (p.s - d.end) / c.speed.max(0.5) > ego_time + GAP_MARGIN
        } else {
            // Along: not beside nor just ahead of the ego in the borrowed lane (a car ahead in
            // the ego's own lane is followed, not passed).
            p.lateral.abs() < 1.0 || p.s < w.ego_s - 15.0 || p.s > d.end + 10.0
        }
    })
}
