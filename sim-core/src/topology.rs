//! The planning graph: every lane sampled into stations, linked along lanes, from a lane's end to
//! its successors, and across to adjacent lanes of the same direction (lane changes).
//!
//! Every edge costs at least the straight-line distance between its ends, so the Euclidean
//! distance to the goal is an admissible and consistent A* heuristic.

use crate::map::{LaneId, LaneMatch, Map};
use crate::math::Vec2;

/// Stations are placed along each lane at most this far apart, metres.
pub const STATION_SPACING: f32 = 5.0;
/// A lane change moves this far forward while crossing to the adjacent lane, metres.
pub const LANE_CHANGE_LENGTH: f32 = 20.0;
/// Extra cost of a lane change, metres, so that routes change lanes only when it pays.
pub const LANE_CHANGE_PENALTY: f32 = 10.0;

/// A point of a lane in the planning graph.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Station {
    pub lane: LaneId,
    /// Arc length along the lane.
    pub s: f32,
    pub pos: Vec2,
}

/// How a route moves from one station to the next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeKind {
    /// Along the same lane.
    Follow,
    /// From a lane's end onto the start of a successor.
    Continue,
    /// Across to an adjacent lane.
    LaneChange,
}

/// The station graph of a map, in compressed adjacency form.
#[derive(Debug, Clone)]
pub struct LaneGraph {
    pub stations: Vec<Station>,
    /// `lane_stations[l]` = the range of station indices of lane `l`, in order of `s`.
    pub lane_stations: Vec<std::ops::Range<usize>>,
    offsets: Vec<usize>,
    edges: Vec<(usize, f32, EdgeKind)>,
}

impl LaneGraph {
    /// Builds the station graph of `map`.
    #[must_use]
    pub fn new(map: &Map) -> Self {
        let mut stations = Vec::new();
        let mut lane_stations = Vec::with_capacity(map.lanes.len());
        for (id, lane) in map.lanes.iter().enumerate() {
            let len = lane.path.length();
            let n = (len / STATION_SPACING).ceil().max(1.0) as usize;
            let first = stations.len();
            for k in 0..=n {
                let s = len * k as f32 / n as f32;
                stations.push(Station { lane: id, s, pos: lane.path.point_at(s) });
            }
            lane_stations.push(first..stations.len());
        }
        let mut adjacency: Vec<Vec<(usize, f32, EdgeKind)>> = vec![Vec::new(); stations.len()];
        for (id, lane) in map.lanes.iter().enumerate() {
            let range = lane_stations[id].clone();
            for i in range.start..range.end - 1 {
                let cost = stations[i + 1].s - stations[i].s;
                adjacency[i].push((i + 1, cost, EdgeKind::Follow));
            }
            let last = range.end - 1;
            for &succ in &lane.successors {
                // Lanes end exactly where their successors start: a zero-length hop.
                let first = lane_stations[succ].start;
                let gap = stations[last].pos.distance(stations[first].pos);
                adjacency[last].push((first, gap, EdgeKind::Continue));
            }
            for neighbour in [lane.left, lane.right].into_iter().flatten() {
                let target = &lane_stations[neighbour];
                let n_len = map.lanes[neighbour].path.length();
                for i in range.clone() {
                    // The same place on the neighbour, LANE_CHANGE_LENGTH further on.
                    let s_target = stations[i].s / lane.path.length() * n_len + LANE_CHANGE_LENGTH;
                    if s_target > n_len - 1.0 {
                        break;
                    }
                    let j = target.clone().find(|&j| stations[j].s >= s_target).unwrap_or(target.end - 1);
                    let straight = stations[i].pos.distance(stations[j].pos);
                    adjacency[i].push((j, straight + LANE_CHANGE_PENALTY, EdgeKind::LaneChange));
                }
            }
        }
        let mut offsets = Vec::with_capacity(stations.len() + 1);
        let mut edges = Vec::new();
        for list in adjacency {
            offsets.push(edges.len());
            edges.extend(list);
        }
        offsets.push(edges.len());
        Self { stations, lane_stations, offsets, edges }
    }

    /// Edges leaving station `u`: (target, cost, kind).
    #[must_use]
    pub fn edges(&self, u: usize) -> &[(usize, f32, EdgeKind)] {
        &self.edges[self.offsets[u]..self.offsets[u + 1]]
    }

    /// The first station of `at.lane` at or after `at.s`.
    #[must_use]
    pub fn station_after(&self, at: LaneMatch) -> usize {
        let r = self.lane_stations[at.lane].clone();
        r.clone().find(|&i| self.stations[i].s >= at.s - 1e-3).unwrap_or(r.end - 1)
    }

    /// The last station of `at.lane` at or before `at.s`.
    #[must_use]
    pub fn station_before(&self, at: LaneMatch) -> usize {
        let r = self.lane_stations[at.lane].clone();
        r.clone().rev().find(|&i| self.stations[i].s <= at.s + 1e-3).unwrap_or(r.start)
    }
}
