//! The road map: roads, lanes, junctions, static obstacles and the drivable-surface raster.
//!
//! A [`Map`] is immutable once built and shared (`Arc<Map>`) by every environment of a process.
//! This file holds the map's types and queries; `Map::from_text` (in `load.rs`) reads the text
//! format (`format.rs`) and builds the geometry (`build.rs`).

mod build;
mod connectors;
pub mod format;
mod load;
pub mod opendrive;
mod surface;

use crate::math::Vec2;
use crate::polyline::Polyline;
pub use format::{MapError, MapSpec, MapWarning};
pub use load::MapFileError;
pub use surface::{SHADE, Surface, SurfaceRaster};

/// Index of a lane in [`Map::lanes`].
pub type LaneId = usize;
/// Index of a junction in [`Map::junctions`].
pub type JunctionId = usize;
/// Index of a road in [`Map::roads`].
pub type RoadId = usize;

/// The default town, embedded in the binary: the town agents train on.
pub const DEFAULT_TOWN: &str = include_str!("default_town.map");
/// The held-out town, embedded in the binary: a second layout no training run uses, with its own
/// seven evaluation routes, to test whether an agent generalises.
pub const HELD_OUT_TOWN: &str = include_str!("held_out_town.map");
/// The embedded towns by name (their `map name=`), the default first.
pub const EMBEDDED_TOWNS: [(&str, &str); 2] = [("default_town", DEFAULT_TOWN), ("held_out_town", HELD_OUT_TOWN)];

/// A built road map.
#[derive(Debug, Clone)]
pub struct Map {
    pub name: String,
    pub roads: Vec<Road>,
    pub lanes: Vec<Lane>,
    pub junctions: Vec<Junction>,
    pub obstacles: Vec<StaticObstacle>,
    pub overpasses: Vec<Overpass>,
    pub surface: SurfaceRaster,
    /// Values that loaded but look like mistakes (`format::MapWarning`); the caller shows them.
    pub warnings: Vec<MapWarning>,
}

/// A road between two nodes: its centre line and lanes.
#[derive(Debug, Clone)]
pub struct Road {
    pub name: String,
    /// The centre line from the start node to the end node.
    pub centre: Polyline,
    pub lane_width: f32,
    pub shoulder: f32,
    pub sidewalk: f32,
    /// Traffic speed limit, m/s.
    pub speed_limit: f32,
    /// Lanes travelling start → end, innermost first.
    pub forward: Vec<LaneId>,
    /// Lanes travelling end → start, innermost first.
    pub backward: Vec<LaneId>,
    /// Arc length of the centre line taken by the junction at each end (0 if none).
    pub cut_start: f32,
    pub cut_end: f32,
}

impl Road {
    /// Drivable half-width on the left of the centre line (backward lanes and shoulder).
    #[must_use]
    pub fn left_width(&self) -> f32 {
        self.backward.len() as f32 * self.lane_width + self.shoulder
    }

    /// Drivable half-width on the right of the centre line (forward lanes and shoulder).
    #[must_use]
    pub fn right_width(&self) -> f32 {
        self.forward.len() as f32 * self.lane_width + self.shoulder
    }
}

/// Where a lane lies: on a road, or across a junction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneKind {
    /// A lane of a road; `index` 0 is next to the centre line.
    Road { road: RoadId, forward: bool, index: usize },
    /// A connector across a junction from one road lane to another.
    Connector { junction: JunctionId, from: LaneId, to: LaneId, turn: Turn },
}

/// The manoeuvre a connector makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Turn {
    Straight,
    Left,
    Right,
}

/// A directed lane: a centre polyline in the direction of travel.
#[derive(Debug, Clone)]
pub struct Lane {
    pub kind: LaneKind,
    pub path: Polyline,
    pub width: f32,
    /// Traffic speed limit, m/s.
    pub speed_limit: f32,
    /// Lanes a vehicle may continue onto at the end of this one.
    pub successors: Vec<LaneId>,
    /// Adjacent lane of the same direction on the left, if any.
    pub left: Option<LaneId>,
    /// Adjacent lane of the same direction on the right, if any.
    pub right: Option<LaneId>,
    /// The junction this lane ends at (entered through one of `successors`), if any.
    pub ends_at_junction: Option<JunctionId>,
}

/// A junction: the area where roads meet, and the connectors across it.
#[derive(Debug, Clone)]
pub struct Junction {
    pub centre: Vec2,
    /// Convex outline of the junction area, counter-clockwise.
    pub outline: Vec<Vec2>,
    pub connectors: Vec<LaneId>,
    /// For each connector (by position in `connectors`), the positions of the connectors whose
    /// paths come close enough that two vehicles on them could touch.
    pub conflicts: Vec<Vec<usize>>,
}

/// What a static obstacle is; collisions report it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ObstacleKind {
    Building,
    Pole,
    Pillar,
}

/// A static obstacle as an oriented box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticObstacle {
    pub kind: ObstacleKind,
    pub centre: Vec2,
    pub half_extents: Vec2,
    /// Radians.
    pub angle: f32,
    /// Metres above ground (for the camera).
    pub height: f32,
}

/// An overpass deck above the roads (only its pillars are obstacles).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overpass {
    pub a: Vec2,
    pub b: Vec2,
    pub width: f32,
    /// Height of the deck's underside, metres.
    pub clearance: f32,
    pub thickness: f32,
}

/// A lane position close to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneMatch {
    pub lane: LaneId,
    pub s: f32,
    pub distance: f32,
}

impl Map {
    /// Road by name.
    #[must_use]
    pub fn road_by_name(&self, name: &str) -> Option<RoadId> {
        self.roads.iter().position(|r| r.name == name)
    }

    /// The road lane closest to `p` whose direction is within 60° of `heading` (or any direction
    /// when `heading` is `None`). Connectors are not considered: vehicles start and stop on roads.
    #[must_use]
    pub fn nearest_road_lane(&self, p: Vec2, heading: Option<f32>) -> Option<LaneMatch> {
        let mut best: Option<LaneMatch> = None;
        for (id, lane) in self.lanes.iter().enumerate() {
            if matches!(lane.kind, LaneKind::Connector { .. }) {
                continue;
            }
            let proj = lane.path.project(p);
            if best.is_some_and(|b| b.distance <= proj.distance) {
                continue;
            }
            if let Some(h) = heading {
                let dh = crate::math::wrap_angle(lane.path.heading_at(proj.s) - h);
                if dh.abs() > 60f32.to_radians() {
                    continue;
                }
            }
            best = Some(LaneMatch { lane: id, s: proj.s, distance: proj.distance });
        }
        best
    }

    /// Whether a ground point is on the drivable surface (lanes, shoulders, junctions).
    #[must_use]
    pub fn is_drivable(&self, p: Vec2) -> bool {
        self.surface.at(p).is_drivable()
    }
}
