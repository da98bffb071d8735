//! The route planner on the default town: A* optimality against a plain Dijkstra over the same
//! station graph, the geometry of planned routes, and the route tracker's distance `d`.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::config::EnvConfig;
use sim_core::map::{LaneId, LaneKind, LaneMatch};
use sim_core::math::{Vec2, left_normal};
use sim_core::route::{Route, RouteTracker, plan};
use sim_core::scenario::{EvalRoute, eval_route};
use sim_core::topology::{LANE_CHANGE_LENGTH, LANE_CHANGE_PENALTY, STATION_SPACING};
use sim_core::town::Town;

/// Number of random origin–destination pairs (the brief asks for about 200).
const PAIRS: usize = 200;

/// The waypoint spacing of the environment's default configuration (the paper's 8 m).
fn spacing() -> f32 {
    EnvConfig::default().waypoint_spacing
}

/// A uniformly random position on a road lane (connectors excluded, as for `plan`'s callers).
fn random_position(town: &Town, rng: &mut ChaCha8Rng) -> LaneMatch {
    let lanes = &town.map.lanes;
    let road_lanes: Vec<LaneId> = (0..lanes.len()).filter(|&l| matches!(lanes[l].kind, LaneKind::Road { .. })).collect();
    let lane = road_lanes[rng.random_range(0..road_lanes.len())];
    let s = rng.random_range(0.0..=lanes[lane].path.length());
    LaneMatch { lane, s, distance: 0.0 }
}

/// Cheapest cost from `from` to `to` by a plain Dijkstra (f64, binary heap) over `town.graph`,
/// with exactly the start and finish costs `route::plan` uses: enter at the first station at or
/// after the origin (paying the straight line to it), leave from the last station at or before the
/// destination (paying the straight line from it), and the direct same-lane case when no station
/// lies between origin and destination.
fn dijkstra_cost(town: &Town, from: LaneMatch, to: LaneMatch) -> Option<f64> {
    let g = &town.graph;
    let st = &g.stations;
    let start_pos = town.map.lanes[from.lane].path.point_at(from.s);
    let goal_pos = town.map.lanes[to.lane].path.point_at(to.s);
    let first = g.station_after(from);
    let last = g.station_before(to);
    if from.lane == to.lane && to.s >= from.s && first > last {
        return Some(f64::from(to.s - from.s));
    }
    let mut dist = vec![f64::INFINITY; st.len()];
    dist[first] = f64::from(start_pos.distance(st[first].pos));
    // Costs are non-negative: order the heap by the bits of the f64 (monotone for x >= 0).
    let mut heap = BinaryHeap::new();
    heap.push(Reverse((dist[first].to_bits(), first)));
    while let Some(Reverse((bits, u))) = heap.pop() {
        let du = f64::from_bits(bits);
        if du > dist[u] {
            continue;
        }
        for &(v, c, _) in g.edges(u) {
            assert!(c >= 0.0, "negative edge cost {c} from station {u}");
            let dv = du + f64::from(c);
            if dv < dist[v] {
                dist[v] = dv;
                heap.push(Reverse((dv.to_bits(), v)));
            }
        }
    }
    dist[last].is_finite().then(|| dist[last] + f64::from(st[last].pos.distance(goal_pos)))
}

/// Seeded random pairs and what `plan` made of them.
fn random_plans(seed: u64) -> Vec<(LaneMatch, LaneMatch, Option<Route>)> {
    let town = Town::default_town();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..PAIRS)
        .map(|_| {
            let (a, b) = (random_position(&town, &mut rng), random_position(&town, &mut rng));
            (a, b, plan(&town.map, &town.graph, a, b, spacing()))
        })
        .collect()
}

#[test]
fn astar_cost_matches_dijkstra_and_reachability_agrees() {
    let town = Town::default_town();
    let mut reachable = 0;
    let mut unreachable = 0;
    for (k, (a, b, route)) in random_plans(11).into_iter().enumerate() {
        let reference = dijkstra_cost(&town, a, b);
        match (&route, reference) {
            (Some(r), Some(c)) => {
                reachable += 1;
                let tol = 1e-2 * c.max(1.0);
                assert!((f64::from(r.cost) - c).abs() <= tol, "pair {k} {a:?} -> {b:?}: A* cost {} vs Dijkstra {c}", r.cost);
            }
            (None, None) => unreachable += 1,
            (r, c) => panic!("pair {k} {a:?} -> {b:?}: plan gives {:?}, Dijkstra gives {c:?}", r.as_ref().map(|r| r.cost)),
        }
    }
    // The default town has three dead-end roads (highway_curve, sharp_bend, under_bridge end at
    // nodes nothing else reaches), so some random pairs cannot be joined; most can. Both outcomes
    // must occur for the comparison to mean anything.
    assert!(reachable >= PAIRS / 2, "only {reachable} of {PAIRS} pairs reachable");
    assert!(unreachable > 0, "no unreachable pair among {PAIRS}: the reachability comparison was never exercised");
}

/// Arc length of `w` along `pts`, searching forward from segment `from` for the first segment
/// that `w` lies on (within 1 mm). Returns (arc length, segment).
fn locate(pts: &[Vec2], w: Vec2, from: usize) -> Option<(f32, usize)> {
    let mut acc: f32 = pts[..=from].windows(2).map(|s| s[0].distance(s[1])).sum();
    for i in from..pts.len() - 1 {
        let (a, b) = (pts[i], pts[i + 1]);
        let ab = b - a;
        let t = ((w - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        if (a + ab * t).distance(w) < 1e-3 {
            return Some((acc + t * ab.length(), i));
        }
        acc += ab.length();
    }
    None
}

/// Number of lane changes in a route: consecutive route lanes that are left/right neighbours.
fn lane_changes(town: &Town, route: &Route) -> usize {
    route
        .lanes
        .windows(2)
        .filter(|w| {
            let l = &town.map.lanes[w[0].0];
            l.left == Some(w[1].0) || l.right == Some(w[1].0)
        })
        .count()
}

#[test]
fn route_geometry_is_continuous_and_waypoints_are_evenly_spaced() {
    let town = Town::default_town();
    let spacing = spacing();
    let mut checked = 0;
    let mut with_lane_change = 0;
    for (k, (a, b, route)) in random_plans(23).into_iter().enumerate() {
        let Some(route) = route else { continue };
        checked += 1;
        let pts = route.path.points();
        let start = town.map.lanes[a.lane].path.point_at(a.s);
        let goal = town.map.lanes[b.lane].path.point_at(b.s);
        assert!(pts[0].distance(start) < 1e-3, "pair {k}: path starts at {:?}, origin lane point {start:?}", pts[0]);
        assert!(pts[pts.len() - 1].distance(goal) < 1e-3, "pair {k}: path ends at {:?}, destination {goal:?}", pts[pts.len() - 1]);

        // No jumps: lane geometry is sampled every 1 m and connectors every 0.5 m (map/build.rs),
        // so consecutive points are < 2 m apart. The one exception by design is a lane change,
        // a straight line to a station LANE_CHANGE_LENGTH ahead on the adjacent lane (at most one
        // STATION_SPACING further, and one 3.5 m lane across).
        let max_change = (LANE_CHANGE_LENGTH + STATION_SPACING + 0.5).hypot(3.5 + 0.5);
        let mut acc = 0.0f32;
        for (i, w) in pts.windows(2).enumerate() {
            let len = w[0].distance(w[1]);
            if len >= 2.0 {
                let entered = route.lanes.iter().position(|&(_, s)| (s - (acc + len)).abs() < 1e-2);
                let is_change = entered.is_some_and(|e| {
                    e > 0 && {
                        let prev = &town.map.lanes[route.lanes[e - 1].0];
                        prev.left == Some(route.lanes[e].0) || prev.right == Some(route.lanes[e].0)
                    }
                });
                assert!(is_change && len <= max_change, "pair {k}: {len} m jump at path segment {i} (s = {acc}) that is not a lane change");
            }
            acc += len;
        }
        let changes = lane_changes(&town, &route);
        if changes > 0 {
            with_lane_change += 1;
        }

        // The cost counts the path's length plus LANE_CHANGE_PENALTY per lane change (topology.rs);
        // it differs only by chord-versus-lane differences over the first and last station gap.
        let excess = route.cost - changes as f32 * LANE_CHANGE_PENALTY - acc;
        assert!(excess.abs() < 0.1 + 1e-4 * acc, "pair {k}: cost {} for a {acc} m path with {changes} lane changes", route.cost);

        // Waypoints: every `spacing` metres of arc length from the start, plus the end point.
        let wps = &route.waypoints;
        assert!(wps.len() >= 2, "pair {k}: {} waypoints", wps.len());
        let mut seg = 0;
        let mut arc = Vec::with_capacity(wps.len());
        for (i, &w) in wps.iter().enumerate() {
            let (s, found) = locate(pts, w, seg).unwrap_or_else(|| panic!("pair {k}: waypoint {i} {w:?} is not on the path ahead"));
            arc.push(s);
            seg = found;
        }
        assert_eq!(arc[0], 0.0, "pair {k}: first waypoint is not the start");
        assert!((arc[arc.len() - 1] - acc).abs() < 1e-2, "pair {k}: last waypoint at {} of {acc} m", arc[arc.len() - 1]);
        for (i, g) in arc.windows(2).map(|w| w[1] - w[0]).enumerate() {
            if i + 2 < arc.len() {
                assert!((g - spacing).abs() < 1e-2, "pair {k}: waypoints {i} and {} are {g} m apart along the path, not {spacing}", i + 1);
            } else {
                assert!(g > -1e-3 && g <= spacing + 1e-2, "pair {k}: last waypoint gap {g} m");
            }
        }
    }
    assert!(checked >= PAIRS / 2, "only {checked} routes planned");
    // The highway (2+2 lanes) makes some routes change lanes; make sure that case was seen.
    assert!(with_lane_change > 0, "no route with a lane change among {checked}: the exception above was never exercised");
}

/// Brute force: distance to the nearest waypoint at index >= `from`.
fn nearest_from(wps: &[Vec2], from: usize, p: Vec2) -> f32 {
    wps[from..].iter().map(|w| w.distance(p)).fold(f32::INFINITY, f32::min)
}

#[test]
fn tracker_reports_the_nearest_waypoint_ahead() {
    let town = Town::default_town();
    let spacing = spacing();
    let mut routes: Vec<Route> = random_plans(5).into_iter().filter_map(|(_, _, r)| r).filter(|r| r.length() > 40.0).take(25).collect();
    routes.extend(EvalRoute::ALL.iter().map(|&r| eval_route(&town, r, spacing).expect("evaluation routes plan on the default town")));
    for (k, route) in routes.iter().enumerate() {
        let wps = &route.waypoints;
        let mut tracker = RouteTracker::default();
        let mut s = 0.0f32;
        while s <= route.length() {
            // Weave up to 1.5 m either side of the centre line (half a lane).
            let lateral = 1.5 * (s / 5.0).sin();
            let p = route.path.point_at(s) + left_normal(route.path.tangent_at(s)) * lateral;
            let prev = tracker.waypoint;
            let t = tracker.update(route, p);
            let brute = nearest_from(wps, prev, p);
            assert!((t.d - brute).abs() < 1e-4, "route {k}, s = {s}: d = {} but the nearest waypoint from #{prev} is {brute} away", t.d);
            assert!(tracker.waypoint >= prev, "route {k}, s = {s}: tracker went back from #{prev} to #{}", tracker.waypoint);
            assert!((wps[tracker.waypoint].distance(p) - t.d).abs() < 1e-4, "route {k}: reported waypoint is not at distance d");
            // Moving forward along the route, the nearest waypoint is within half a spacing of
            // arc length (plus the lateral offset), so d can never exceed that.
            assert!(t.d <= spacing / 2.0 + lateral.abs() + 1e-3, "route {k}, s = {s}: d = {} too large", t.d);
            s += 0.7;
        }
        assert!(tracker.waypoint + 2 >= wps.len(), "route {k}: ended at waypoint #{} of {}", tracker.waypoint, wps.len());
    }
}

#[test]
fn tracker_never_searches_behind_progress() {
    let town = Town::default_town();
    let spacing = spacing();
    // A straight 140 m highway stretch (scenario.rs): Euclidean and route distances agree.
    let route = eval_route(&town, EvalRoute::StraightHighway, spacing).expect("straight_highway plans");
    let wps = &route.waypoints;
    let mut tracker = RouteTracker::default();
    let target = 0.6 * route.length();
    let mut s = 0.0;
    while s < target {
        tracker.update(&route, route.path.point_at(s));
        s += 1.0;
    }
    let progress = tracker.waypoint;
    // The waypoint nearest to s ≈ 0.6 · 140 = 84 m is #10 or #11 (84 / 8 m spacing = 10.5).
    assert!((10..=11).contains(&progress), "progress reached waypoint #{progress}, expected #10 or #11");

    // Jump back near the start: the first waypoint is 1 m away, but it lies behind progress.
    let back = route.path.point_at(1.0);
    let t = tracker.update(&route, back);
    assert!(wps[0].distance(back) < 1.01);
    assert_eq!(tracker.waypoint, progress, "the tracker moved its waypoint index behind progress");
    assert!((t.d - wps[progress].distance(back)).abs() < 1e-4, "d = {} is not the distance to the progress waypoint", t.d);
    assert!(t.d > 60.0, "d = {} m: the tracker looked at waypoints behind its progress", t.d);
    assert!((t.d - nearest_from(wps, progress, back)).abs() < 1e-4);
}
