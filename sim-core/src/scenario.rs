//! Episodes' starting conditions: random training routes, and the seven evaluation routes of the
//! paper's Table I as named scenarios on the default town.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use crate::map::{LaneId, LaneKind, LaneMatch, Map, Turn};
use crate::route::{Route, plan};
use crate::route_types::{Place, RouteShape, find};
use crate::town::Town;

/// What an episode drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scenario {
    /// A random origin–destination pair whose route length is within the configured range.
    Random,
    /// One of the paper's seven evaluation routes.
    Eval(EvalRoute),
}

/// The paper's seven route types (Table I).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EvalRoute {
    StraightHighway,
    StraightUrban,
    StraightUnderBridge,
    SlightCurve,
    SharpCurve,
    RightTurn,
    LeftTurn,
}

impl EvalRoute {
    /// All seven, in the paper's order.
    pub const ALL: [EvalRoute; 7] = [
        EvalRoute::StraightHighway,
        EvalRoute::StraightUrban,
        EvalRoute::StraightUnderBridge,
        EvalRoute::SlightCurve,
        EvalRoute::SharpCurve,
        EvalRoute::RightTurn,
        EvalRoute::LeftTurn,
    ];

    /// The route's name on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            EvalRoute::StraightHighway => "straight_highway",
            EvalRoute::StraightUrban => "straight_urban",
            EvalRoute::StraightUnderBridge => "straight_under_bridge",
            EvalRoute::SlightCurve => "slight_curve",
            EvalRoute::SharpCurve => "sharp_curve",
            EvalRoute::RightTurn => "right_turn",
            EvalRoute::LeftTurn => "left_turn",
        }
    }

    /// The route with this name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|r| r.name() == name)
    }

    /// The paper's Table I scores (Hybrid-DQN, human), for reference columns.
    #[must_use]
    pub fn paper_scores(self) -> (f32, f32) {
        match self {
            EvalRoute::StraightHighway => (21.1, 43.4),
            EvalRoute::StraightUrban => (27.6, 38.1),
            EvalRoute::StraightUnderBridge => (31.6, 45.2),
            EvalRoute::SlightCurve => (30.4, 49.5),
            EvalRoute::SharpCurve => (-74.4, -8.9),
            EvalRoute::RightTurn => (-136.9, -12.1),
            EvalRoute::LeftTurn => (-385.9, -25.5),
        }
    }

    /// Origin and destination on the embedded town `town`: (road, forward?, lane index, station
    /// along the road's centre line from its start node). Forward lane 0 is next to the centre
    /// line; a right turn starts in the rightmost lane and a left turn in the leftmost.
    fn ends(self, town: &str) -> Option<[(&'static str, bool, usize, f32); 2]> {
        Some(match town {
            "default_town" => self.default_town_ends(),
            "held_out_town" => self.held_out_town_ends(),
            _ => return None,
        })
    }

    fn held_out_town_ends(self) -> [(&'static str, bool, usize, f32); 2] {
        match self {
            // Eastbound right lane of the arterial west of J1, 140 m of straight.
            EvalRoute::StraightHighway => [("art_west", true, 1, 20.0), ("art_west", true, 1, 160.0)],
            // Northbound across the arterial at the multi-lane 4-way junction J1.
            EvalRoute::StraightUrban => [("st_s", true, 0, 50.0), ("st_n", true, 0, 60.0)],
            // Eastbound on the arterial under the overpass at x = 560.
            EvalRoute::StraightUnderBridge => [("art_east", true, 0, 60.0), ("art_east", true, 0, 250.0)],
            // The rural road's 18° bend of radius 400 m.
            EvalRoute::SlightCurve => [("rural", true, 0, 15.0), ("rural", true, 0, 255.0)],
            // The 90° left bend of radius 25 m.
            EvalRoute::SharpCurve => [("bend", true, 0, 12.0), ("bend", true, 0, 135.0)],
            // Eastbound on the arterial's right lane, right at J2 into the side street.
            EvalRoute::RightTurn => [("art_mid", true, 1, 60.0), ("st_j2", true, 0, 70.0)],
            // Northbound up the side street, left at J2, west on the arterial's left lane.
            EvalRoute::LeftTurn => [("st_j2", false, 0, 90.0), ("art_mid", false, 0, 110.0)],
        }
    }

    fn default_town_ends(self) -> [(&'static str, bool, usize, f32); 2] {
        match self {
            // Eastbound right lane of the highway, 140 m of straight.
            EvalRoute::StraightHighway => [("highway", true, 1, 50.0), ("highway", true, 1, 190.0)],
            // Northbound through the 4-way junction E.
            EvalRoute::StraightUrban => [("b_e", true, 0, 40.0), ("e_h", true, 0, 60.0)],
            // Northbound under the overpass at y = 290.
            EvalRoute::StraightUnderBridge => [("under_bridge", true, 0, 15.0), ("under_bridge", true, 0, 145.0)],
            // Highway into its 25° bend of radius 250 m.
            EvalRoute::SlightCurve => [("highway", true, 1, 320.0), ("highway_curve", true, 1, 135.0)],
            // The 90° bend of radius 18 m.
            EvalRoute::SharpCurve => [("sharp_bend", true, 0, 12.0), ("sharp_bend", true, 0, 105.0)],
            // Eastbound on d_e, right at E, south on b_e (its backward lane).
            EvalRoute::RightTurn => [("d_e", true, 0, 30.0), ("b_e", false, 0, 40.0)],
            // Eastbound on d_e, left at E, north on e_h.
            EvalRoute::LeftTurn => [("d_e", true, 0, 30.0), ("e_h", true, 0, 60.0)],
        }
    }

    /// What a route of this type looks like, for finding one in a map without named places (the
    /// same bounds `sim-core/tests/it/world.rs` checks the embedded towns' routes against).
    #[must_use]
    pub fn shape(self) -> RouteShape {
        let (place, turn_deg, either_way) = match self {
            EvalRoute::StraightHighway => (Place::Highway, 0.0..5.0, true),
            EvalRoute::StraightUrban => (Place::Junction, 0.0..5.0, true),
            EvalRoute::StraightUnderBridge => (Place::UnderBridge, 0.0..5.0, true),
            EvalRoute::SlightCurve => (Place::Road, 10.0..40.0, true),
            EvalRoute::SharpCurve => (Place::Road, 80.0..100.0, true),
            EvalRoute::RightTurn => (Place::Turn(Turn::Right), -100.0..-80.0, false),
            EvalRoute::LeftTurn => (Place::Turn(Turn::Left), 80.0..100.0, false),
        };
        RouteShape { place, turn_deg, either_way }
    }

    /// The route's origin and destination on `town`: its named place on an embedded town, else
    /// the first place of its shape found in the map (`route_types.rs`, searched once per town).
    #[must_use]
    pub fn endpoints_in(self, town: &Town) -> Option<[LaneMatch; 2]> {
        if let Some(ends) = self.endpoints(&town.map) {
            return Some(ends);
        }
        let found = town.found_routes.get_or_init(|| EvalRoute::ALL.iter().map(|r| find(town, &r.shape())).collect());
        found[EvalRoute::ALL.iter().position(|&r| r == self)?]
    }

    /// The route's origin and destination as lane positions on `map`. `None` if the map is not
    /// an embedded town (by its name) or lacks the roads.
    #[must_use]
    pub fn endpoints(self, map: &Map) -> Option<[LaneMatch; 2]> {
        let [a, b] = self.ends(&map.name)?;
        Some([lane_position(map, a)?, lane_position(map, b)?])
    }
}

fn lane_position(map: &Map, (road, forward, index, station): (&str, bool, usize, f32)) -> Option<LaneMatch> {
    let r = &map.roads[map.road_by_name(road)?];
    let lane = *if forward { r.forward.get(index)? } else { r.backward.get(index)? };
    let p = r.centre.point_at(station);
    let proj = map.lanes[lane].path.project(p);
    Some(LaneMatch { lane, s: proj.s, distance: proj.distance })
}

/// A random drive gives up after this many lane hops (see `random_route`).
const MAX_HOPS: usize = 10_000;

/// Draws a random origin and destination whose planned route is `min..=max` metres long: a random
/// origin on a road lane, a random drive along the lane graph for a random length, then A* back
/// over the whole graph (which may find a shorter way). Tries up to 200 times.
#[must_use]
pub fn random_route(town: &Town, min: f32, max: f32, spacing: f32, rng: &mut ChaCha8Rng) -> Option<Route> {
    let lanes = &town.map.lanes;
    let road_lanes: Vec<LaneId> = (0..lanes.len()).filter(|&l| matches!(lanes[l].kind, LaneKind::Road { .. })).collect();
    for _ in 0..200 {
        let lane = road_lanes[rng.random_range(0..road_lanes.len())];
        let len = lanes[lane].path.length();
        if len < 10.0 {
            continue;
        }
        let s = rng.random_range(2.0..len - 2.0);
        let target = rng.random_range(min..=max);
        // Random drive.
        let (mut cur, mut cur_s, mut left) = (lane, s, target);
        let mut hops = 0usize;
        let goal = loop {
            let remaining = lanes[cur].path.length() - cur_s;
            let is_road = matches!(lanes[cur].kind, LaneKind::Road { .. });
            if remaining >= left && is_road && cur_s + left > 2.0 {
                break Some(cur_s + left);
            }
            let succ = &lanes[cur].successors;
            // Once `left` is clamped to 1 m no road lane can hold the goal (it needs `cur_s + left
            // > 2`): the walk then ends only at a dead end, which a map without any (an OpenDRIVE
            // town) lacks; give up after a bound instead of walking forever.
            hops += 1;
            if succ.is_empty() || hops > MAX_HOPS {
                break None;
            }
            left = (left - remaining).max(1.0);
            cur = succ[rng.random_range(0..succ.len())];
            cur_s = 0.0;
        };
        let Some(goal_s) = goal else { continue };
        let from = LaneMatch { lane, s, distance: 0.0 };
        let to = LaneMatch { lane: cur, s: goal_s.min(lanes[cur].path.length() - 1.0), distance: 0.0 };
        if let Some(route) = plan(&town.map, &town.graph, from, to, spacing)
            && (min..=max).contains(&route.length())
        {
            return Some(route);
        }
    }
    None
}

/// The planned route of an evaluation scenario.
#[must_use]
pub fn eval_route(town: &Town, route: EvalRoute, spacing: f32) -> Option<Route> {
    let [from, to] = route.endpoints_in(town)?;
    plan(&town.map, &town.graph, from, to, spacing)
}
