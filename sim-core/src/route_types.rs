//! Finding routes of a given type in any map: the seven route types of the paper's Table I are
//! named places on the embedded towns, but a user's map (an OpenDRIVE file) has no names. A route
//! type is a shape — straight, a slight or sharp bend, a turn at a junction — with a place
//! (a highway, an urban junction, under an overpass); this file proposes candidate origin and
//! destination pairs in a fixed order and keeps the first whose planned route has the shape, with
//! the tests the embedded towns' routes pass (`sim-core/tests/it/world.rs`).

use crate::map::{LaneKind, LaneMatch, Map, Turn};
use crate::route::{Route, plan};
use crate::town::Town;

/// Where the route must run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// Along one road (no junction), fast (≥ `HIGHWAY_SPEED`) or with two lanes each way.
    Highway,
    /// Straight across a junction.
    Junction,
    /// Under an overpass deck.
    UnderBridge,
    /// Along roads, no junction.
    Road,
    /// Through a junction, turning this way.
    Turn(Turn),
}

/// What a route of a type looks like.
#[derive(Debug, Clone, PartialEq)]
pub struct RouteShape {
    pub place: Place,
    /// Heading change from origin to destination, degrees (positive: left), as `min..max`.
    pub turn_deg: std::ops::Range<f32>,
    /// Whether the heading change's sign does not matter (curves bend either way).
    pub either_way: bool,
}

/// Routes are this long, metres.
pub const LENGTH: std::ops::Range<f32> = 80.0..300.0;
/// A road this fast (m/s, 80 km/h) is a highway.
const HIGHWAY_SPEED: f32 = 22.0;
/// Candidate windows along a lane start this far apart, metres.
const WINDOW_STEP: f32 = 10.0;
/// Candidate window lengths along a lane, metres.
const WINDOWS: [f32; 4] = [100.0, 140.0, 200.0, 280.0];
/// The route's origin lies this far before a junction it crosses, and its destination this far
/// after, metres (less on shorter lanes).
const APPROACH: f32 = 60.0;
/// Waypoint spacing of the candidate routes (their shape, not their waypoints, is checked).
const SPACING: f32 = 8.0;

impl RouteShape {
    fn accepts(&self, map: &Map, route: &Route) -> bool {
        let p = &route.path;
        let turn = libm::remainderf(p.heading_at(p.length()) - p.heading_at(0.0), std::f32::consts::TAU).to_degrees();
        let turn = if self.either_way { turn.abs() } else { turn };
        if !self.turn_deg.contains(&turn) || !LENGTH.contains(&route.length()) {
            return false;
        }
        // Connectors a vehicle had a choice at; a bend drawn as a junction of two roads (as
        // RoadRunner exports corners) is a curve, not a turn.
        let turns: Vec<Turn> = route
            .lanes
            .iter()
            .filter_map(|&(l, _)| match map.lanes[l].kind {
                LaneKind::Connector { turn, from, .. } if map.lanes[from].successors.len() > 1 || self.place != Place::Road => Some(turn),
                _ => None,
            })
            .collect();
        match self.place {
            Place::Highway | Place::Road | Place::UnderBridge => turns.is_empty(),
            Place::Junction => turns == [Turn::Straight],
            Place::Turn(t) => turns == [t],
        }
    }
}

/// The first origin and destination on `town` whose route has `shape`, or `None` if the map has
/// no such place.
#[must_use]
pub fn find(town: &Town, shape: &RouteShape) -> Option<[LaneMatch; 2]> {
    let map = &town.map;
    let at = |lane, s| LaneMatch { lane, s, distance: 0.0 };
    let mut candidates: Vec<[LaneMatch; 2]> = Vec::new();
    match shape.place {
        Place::Junction | Place::Turn(_) => {
            for lane in &map.lanes {
                let LaneKind::Connector { from, to, turn, .. } = lane.kind else { continue };
                let wanted = match shape.place {
                    Place::Turn(t) => t,
                    _ => Turn::Straight,
                };
                if turn != wanted {
                    continue;
                }
                let (la, lb) = (map.lanes[from].path.length(), map.lanes[to].path.length());
                candidates.push([at(from, (la - APPROACH).max(1.0).min(la)), at(to, APPROACH.min(lb - 1.0).max(0.0))]);
            }
        }
        Place::Highway | Place::Road | Place::UnderBridge => {
            if shape.place == Place::Road {
                // Bends through a junction without a choice (see `accepts`).
                for lane in &map.lanes {
                    if let LaneKind::Connector { from, to, .. } = lane.kind
                        && map.lanes[from].successors.len() == 1
                    {
                        let (la, lb) = (map.lanes[from].path.length(), map.lanes[to].path.length());
                        candidates.push([at(from, (la - APPROACH).max(1.0).min(la)), at(to, APPROACH.min(lb - 1.0).max(0.0))]);
                    }
                }
            }
            for (id, lane) in map.lanes.iter().enumerate() {
                let LaneKind::Road { road, .. } = lane.kind else { continue };
                let r = &map.roads[road];
                if shape.place == Place::Highway && lane.speed_limit < HIGHWAY_SPEED && (r.forward.len() < 2 || r.backward.len() < 2) {
                    continue;
                }
                let len = lane.path.length();
                for window in WINDOWS {
                    let mut s = 2.0;
                    while s + window < len - 2.0 {
                        if shape.place != Place::UnderBridge || passes_under(map, &lane.path, s, s + window) {
                            candidates.push([at(id, s), at(id, s + window)]);
                        }
                        s += WINDOW_STEP;
                    }
                }
            }
        }
    }
    candidates.into_iter().find(|&[a, b]| plan(map, &town.graph, a, b, SPACING).is_some_and(|r| shape.accepts(map, &r)))
}

/// Whether the lane between arc lengths `s0` and `s1` passes under an overpass deck.
fn passes_under(map: &Map, path: &crate::polyline::Polyline, s0: f32, s1: f32) -> bool {
    let mut s = s0;
    while s < s1 {
        let p = path.point_at(s);
        for o in &map.overpasses {
            let axis = o.b - o.a;
            let t = ((p - o.a).dot(axis) / axis.length_squared().max(1e-6)).clamp(0.0, 1.0);
            if (o.a + axis * t).distance(p) < o.width / 2.0 {
                return true;
            }
        }
        s += 2.0;
    }
    false
}
