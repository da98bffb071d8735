//! Routes planned by A* on the lane graph: their centre line, waypoints, and the tracker that
//! measures the distance `d` from the vehicle to the closest waypoint ahead.

use crate::astar::astar;
use crate::map::{LaneId, LaneMatch, Map};
use crate::math::Vec2;
use crate::polyline::Polyline;
use crate::topology::{EdgeKind, LaneGraph};

/// A planned route from an origin to a destination.
#[derive(Debug, Clone)]
pub struct Route {
    /// Dense centre line to drive along, origin to destination.
    pub path: Polyline,
    /// Waypoints every `spacing` metres along `path` (the planner's output the agent sees via d).
    pub waypoints: Vec<Vec2>,
    /// The lanes the route uses, in order, with the arc length along `path` where each is entered.
    pub lanes: Vec<(LaneId, f32)>,
    /// A* cost (metres, including lane-change penalties).
    pub cost: f32,
}

impl Route {
    /// Total length of the centre line, metres.
    #[must_use]
    pub fn length(&self) -> f32 {
        self.path.length()
    }

    /// The destination.
    #[must_use]
    pub fn destination(&self) -> Vec2 {
        self.path.end()
    }

    /// The lane of the route at arc length `s` along its path.
    #[must_use]
    pub fn lane_at(&self, s: f32) -> LaneId {
        let i = self.lanes.partition_point(|&(_, start)| start <= s);
        self.lanes[i.saturating_sub(1)].0
    }
}

/// Plans the shortest route from `from` to `to` (lane positions) with A*, waypoints every
/// `spacing` metres. `None` when the destination cannot be reached.
#[must_use]
pub fn plan(map: &Map, graph: &LaneGraph, from: LaneMatch, to: LaneMatch, spacing: f32) -> Option<Route> {
    let start_pos = map.lanes[from.lane].path.point_at(from.s);
    let goal_pos = map.lanes[to.lane].path.point_at(to.s);
    let first = graph.station_after(from);
    let last = graph.station_before(to);
    let st = &graph.stations;
    let same_lane_direct = from.lane == to.lane && to.s >= from.s && first > last;
    let (cost, nodes) = if same_lane_direct {
        (to.s - from.s, Vec::new())
    } else {
        let path = astar(
            st.len(),
            &[(first, start_pos.distance(st[first].pos))],
            |u| (u == last).then(|| st[u].pos.distance(goal_pos)),
            |u, out| out.extend(graph.edges(u).iter().map(|&(v, c, _)| (v, c))),
            |u| st[u].pos.distance(goal_pos),
        )?;
        (path.cost, path.nodes)
    };

    // Centre line: the start point, lane geometry between consecutive stations of a lane, straight
    // lines across lane changes, the goal point.
    let mut pts = vec![start_pos];
    let mut lanes: Vec<(LaneId, f32)> = vec![(from.lane, 0.0)];
    let mut acc = 0.0f32;
    let mut prev = start_pos;
    let push = |p: Vec2, pts: &mut Vec<Vec2>, acc: &mut f32, prev: &mut Vec2| {
        *acc += prev.distance(p);
        *prev = p;
        pts.push(p);
    };
    let mut cur_lane = from.lane;
    let mut cur_s = from.s;
    for (k, &v) in nodes.iter().enumerate() {
        let kind =
            if k == 0 { EdgeKind::Follow } else { graph.edges(nodes[k - 1]).iter().find(|e| e.0 == v).map_or(EdgeKind::Follow, |e| e.2) };
        let target = st[v];
        if kind == EdgeKind::Follow && target.lane == cur_lane {
            for &p in interior_points(&map.lanes[cur_lane].path, cur_s, target.s) {
                push(p, &mut pts, &mut acc, &mut prev);
            }
        }
        if target.lane != cur_lane {
            lanes.push((target.lane, acc + prev.distance(target.pos)));
        }
        push(target.pos, &mut pts, &mut acc, &mut prev);
        cur_lane = target.lane;
        cur_s = target.s;
    }
    if cur_lane == to.lane {
        for &p in interior_points(&map.lanes[cur_lane].path, cur_s, to.s) {
            push(p, &mut pts, &mut acc, &mut prev);
        }
    }
    push(goal_pos, &mut pts, &mut acc, &mut prev);
    let path = Polyline::new(pts)?;
    let waypoints = path.resample(spacing);
    Some(Route { path, waypoints, lanes, cost })
}

/// The vertices of `path` strictly between arc lengths `s0` and `s1`.
fn interior_points(path: &Polyline, s0: f32, s1: f32) -> &[Vec2] {
    if s1 <= s0 {
        return &[];
    }
    let a = path.segment_at(s0) + 1;
    let b = path.segment_at(s1);
    if a > b { &[] } else { &path.points()[a..=b] }
}

/// Follows a vehicle along a route: the closest waypoint (searched over the route ahead of the
/// vehicle's progress) and the arc length reached.
#[derive(Debug, Clone, Default)]
pub struct RouteTracker {
    /// Index of the closest waypoint at the last update; the search never goes back before it.
    pub waypoint: usize,
    /// Path segment of the last projection (a search hint).
    segment: usize,
}

/// What the tracker measured at one position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracking {
    /// Distance to the closest waypoint ahead, metres (the paper's d).
    pub d: f32,
    /// Arc length along the route of the vehicle's projection, metres.
    pub s: f32,
    /// Signed lateral offset from the route's centre line, positive to the left, metres.
    pub lateral: f32,
}

impl RouteTracker {
    /// Updates with the vehicle at `pos`.
    pub fn update(&mut self, route: &Route, pos: Vec2) -> Tracking {
        let wps = &route.waypoints;
        let (mut best, mut best_d2) = (self.waypoint, f32::INFINITY);
        for (i, w) in wps.iter().enumerate().skip(self.waypoint) {
            let d2 = w.distance_squared(pos);
            if d2 < best_d2 {
                best = i;
                best_d2 = d2;
            }
        }
        self.waypoint = best;
        // Project onto the path near the last segment: a window behind and well ahead of it.
        let proj = route.path.project_range(pos, self.segment.saturating_sub(8), self.segment + 64);
        self.segment = proj.segment;
        Tracking { d: best_d2.sqrt(), s: proj.s, lateral: proj.lateral }
    }
}
