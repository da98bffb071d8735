//! A junction's connectors, the lanes across it from one road lane to the next: adding one
//! (linked from the lane it leaves) and which of them conflict. Both map builders (the text
//! format's and OpenDRIVE's) use this one place.

use super::{Lane, LaneId, LaneKind, Turn};
use crate::polyline::Polyline;

/// Two connectors conflict when their centre lines come closer than this, metres.
const CONFLICT_DISTANCE: f32 = 3.2;

/// Adds a connector across junction `junction` from lane `from` to lane `to` and makes it a
/// successor of `from` (which then ends at the junction); returns its id.
pub(super) fn add_connector(
    lanes: &mut Vec<Lane>,
    junction: usize,
    (from, to): (LaneId, LaneId),
    turn: Turn,
    path: Polyline,
    width: f32,
    speed_limit: f32,
) -> LaneId {
    lanes.push(Lane {
        kind: LaneKind::Connector { junction, from, to, turn },
        path,
        width,
        speed_limit,
        successors: vec![to],
        left: None,
        right: None,
        ends_at_junction: None,
    });
    let c = lanes.len() - 1;
    lanes[from].successors.push(c);
    lanes[from].ends_at_junction = Some(junction);
    c
}

/// For each of `connectors` (lane ids into `lanes`), the indices into `connectors` of the others
/// it conflicts with: [`super::Junction::conflicts`].
pub(super) fn conflict_sets(lanes: &[Lane], connectors: &[LaneId]) -> Vec<Vec<usize>> {
    connectors
        .iter()
        .enumerate()
        .map(|(i, &a)| {
            connectors
                .iter()
                .enumerate()
                .filter(|&(j, &b)| j != i && polyline_distance(&lanes[a].path, &lanes[b].path) < CONFLICT_DISTANCE)
                .map(|(j, _)| j)
                .collect()
        })
        .collect()
}

/// The smallest distance between the vertices of one polyline and the segments of the other.
fn polyline_distance(a: &Polyline, b: &Polyline) -> f32 {
    let one_way = |x: &Polyline, y: &Polyline| x.points().iter().map(|&p| y.project(p).distance).fold(f32::INFINITY, f32::min);
    one_way(a, b).min(one_way(b, a))
}
