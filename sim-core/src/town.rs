//! A [`Town`]: a map with everything derived from it once and shared by every environment —
//! the planning graph, the static-obstacle grid, per-lane speed caps, connector indices and
//! the static scenery's render boxes.

use std::sync::Arc;

use crate::camera::scene::{SceneBox, static_boxes};
use crate::collision::StaticGrid;
use crate::map::{JunctionId, LaneId, LaneKind, LaneMatch, Map, MapError};
use crate::topology::LaneGraph;

/// Lateral acceleration traffic accepts in curves, m/s².
const COMFORT_LATERAL_ACCEL: f32 = 2.5;

/// A map and its derived, read-only indices.
#[derive(Debug)]
pub struct Town {
    pub map: Map,
    pub graph: LaneGraph,
    pub statics: StaticGrid,
    /// Per lane: the highest comfortable speed over its sharpest bend, m/s.
    pub curve_speed: Vec<f32>,
    /// Per lane: for connectors, the junction and the connector's position in its list.
    pub connector_slot: Vec<Option<(JunctionId, usize)>>,
    /// The static scenery as the renderers draw it (obstacles, then overpass decks), prepared
    /// once here so that no frame rebuilds it; built by `camera::scene`, which decides its looks.
    pub scene_statics: Vec<SceneBox>,
    /// The evaluation routes found in this map (by position in `EvalRoute::ALL`), searched once
    /// on first use by `scenario::eval_route` for maps whose routes are not named places.
    pub found_routes: std::sync::OnceLock<Vec<Option<[LaneMatch; 2]>>>,
    /// How far the road's edge is, per block of the surface raster (`sensor::rays`), worked out
    /// on the vector sensor's first use.
    pub edge_clearance: std::sync::OnceLock<crate::sensor::rays::EdgeClearance>,
}

impl Town {
    /// Derives everything from `map`.
    #[must_use]
    pub fn new(map: Map) -> Arc<Self> {
        let graph = LaneGraph::new(&map);
        let statics = StaticGrid::new(&map);
        let curve_speed = map.lanes.iter().map(|l| curve_speed(l.path.points())).collect();
        let mut connector_slot = vec![None; map.lanes.len()];
        for (j, junction) in map.junctions.iter().enumerate() {
            for (k, &c) in junction.connectors.iter().enumerate() {
                connector_slot[c] = Some((j, k));
            }
        }
        let scene_statics = static_boxes(&map);
        Arc::new(Self {
            map,
            graph,
            statics,
            curve_speed,
            connector_slot,
            scene_statics,
            found_routes: std::sync::OnceLock::new(),
            edge_clearance: std::sync::OnceLock::new(),
        })
    }

    /// The embedded default town.
    #[must_use]
    pub fn default_town() -> Arc<Self> {
        Self::new(Map::default_town())
    }

    /// An embedded town by name (`default_town`, `held_out_town`, see `map::EMBEDDED_TOWNS`).
    #[must_use]
    pub fn embedded(name: &str) -> Option<Arc<Self>> {
        Map::embedded(name).map(Self::new)
    }

    /// Loads a map from text.
    pub fn from_map_text(text: &str) -> Result<Arc<Self>, MapError> {
        Ok(Self::new(Map::from_text(text)?))
    }

    /// Whether two connectors (lane ids) may not be used at the same time.
    // `#[inline]`: the traffic asks it for every pair of requests at every junction, every step,
    // and a call each showed in the env step's instruction count
    // (experiments/performance/CHANGELOG.md, "the hazards' instructions").
    #[inline]
    #[must_use]
    pub fn connectors_conflict(&self, a: LaneId, b: LaneId) -> bool {
        match (self.connector_slot[a], self.connector_slot[b]) {
            (Some((ja, ia)), Some((jb, ib))) if ja == jb => self.map.junctions[ja].conflicts[ia].contains(&ib),
            _ => false,
        }
    }

    /// Whether `lane` is a junction connector.
    #[must_use]
    pub fn is_connector(&self, lane: LaneId) -> bool {
        matches!(self.map.lanes[lane].kind, LaneKind::Connector { .. })
    }
}

/// Highest speed at which a polyline's sharpest bend (measured over ~3 m) stays within the comfort
/// lateral acceleration.
fn curve_speed(pts: &[crate::math::Vec2]) -> f32 {
    let mut kappa_max = 0.0f32;
    for w in pts.windows(5).step_by(1) {
        let (a, b) = (w[2] - w[0], w[4] - w[2]);
        let len = a.length() + b.length();
        if len < 1e-3 {
            continue;
        }
        let turn = crate::math::atan2(crate::math::cross(a, b), a.dot(b)).abs();
        kappa_max = kappa_max.max(turn / (0.5 * len));
    }
    if kappa_max < 1e-4 { f32::INFINITY } else { (COMFORT_LATERAL_ACCEL / kappa_max).sqrt() }
}
