//! The junction runner's geometry (after scenario_runner's `opposite_vehicle_taking_priority` and
//! `no_signal_junction_crossing`): a junction the ego's route crosses, a connector of it that
//! conflicts with the ego's and crosses its path (straight across from another road), the point
//! where the two paths cross, and when the runner must start from rest to be there with the ego.

use super::config::HazardsConfig;
use crate::map::{LaneId, LaneKind, Turn};
use crate::route::Route;
use crate::town::Town;

/// How far before its stop line the runner waits, metres (room to reach its speed).
pub const RUNNER_APPROACH: f32 = 30.0;
/// The runner's acceleration from rest, m/s².
pub const RUNNER_ACCEL: f32 = 3.5;
/// Until this far from the crossing point the runner times its speed to meet the ego there, from
/// then on it drives at its own, metres.
pub const COMMIT_DISTANCE: f32 = 5.0;
/// Seconds after the ego's centre the runner's is timed to reach the crossing point: its nose
/// then meets the ego's side, past the point where braking would help.
pub const LAG: f32 = 0.3;
/// The slowest it drives while timing, m/s.
pub const MIN_SPEED: f32 = 5.0;
/// The ego needs this much route before the crossing to be at speed, metres.
const EGO_RUN_UP: f32 = 40.0;
/// Room kept after the ego's connector before the destination, metres.
const ROOM_AFTER: f32 = 20.0;
/// Paths crossing at a smaller angle than this (|cos| above it) merge rather than cross.
const MAX_CROSSING_COS: f32 = 0.7;

/// Where a junction runner crosses the ego's route.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The road lane the runner waits on.
    pub approach: LaneId,
    /// The connector it crosses the junction on (conflicting with the ego's).
    pub connector: LaneId,
    /// Route arc length of the crossing point.
    pub s: f32,
    /// Arc length along the runner's connector of the crossing point.
    pub along: f32,
}

/// The crossing on `route` closest to the configured distance range, if the route crosses a
/// junction with room before and after it and a straight connector across its path.
#[must_use]
pub fn find(cfg: &HazardsConfig, town: &Town, route: &Route) -> Option<Crossing> {
    let lanes = &town.map.lanes;
    let mut best: Option<(f32, Crossing)> = None;
    for (i, &(lane, start)) in route.lanes.iter().enumerate() {
        let LaneKind::Connector { junction, from: ego_from, .. } = lanes[lane].kind else { continue };
        let end = route.lanes.get(i + 1).map_or(route.length(), |&(_, s)| s);
        if start < EGO_RUN_UP || end + ROOM_AFTER > route.length() {
            continue;
        }
        let window = (route.path.segment_at(start - 2.0), route.path.segment_at(end + 2.0) + 1);
        for &other in &town.map.junctions[junction].connectors {
            let LaneKind::Connector { from, turn: Turn::Straight, .. } = lanes[other].kind else { continue };
            if other == lane || from == ego_from || !town.connectors_conflict(lane, other) {
                continue;
            }
            if lanes[from].path.length() < RUNNER_APPROACH + 5.0 {
                continue;
            }
            // The point of the runner's path closest to the route: where they cross.
            let path = &lanes[other].path;
            let mut closest: Option<(f32, f32, f32)> = None; // (|lateral|, route s, along)
            let mut along = 0.0;
            while along <= path.length() {
                let p = route.path.project_range(path.point_at(along), window.0, window.1);
                if closest.is_none_or(|(d, _, _)| p.distance < d) {
                    closest = Some((p.distance, p.s, along));
                }
                along += 0.5;
            }
            let Some((distance, s, along)) = closest else { continue };
            let crossing_cos = route.path.tangent_at(s).dot(path.tangent_at(along)).abs();
            if distance > 0.5 || crossing_cos > MAX_CROSSING_COS || s < EGO_RUN_UP {
                continue;
            }
            let miss = (s - cfg.distance.max).max(cfg.distance.min - s).max(0.0);
            if best.as_ref().is_none_or(|&(m, _)| miss < m) {
                best = Some((miss, Crossing { approach: from, connector: other, s, along }));
            }
        }
    }
    best.map(|(_, c)| c)
}

/// Seconds to cover `distance` metres from rest at `accel` up to `speed`, then at `speed`.
#[must_use]
pub fn time_from_rest(distance: f32, speed: f32, accel: f32) -> f32 {
    let run_up = speed * speed / (2.0 * accel);
    if distance <= run_up { (2.0 * distance / accel).sqrt() } else { speed / accel + (distance - run_up) / speed }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_from_rest_accelerates_then_cruises() {
        // 10 m/s at 2.5 m/s²: 4 s and 20 m to reach it.
        assert!((time_from_rest(20.0, 10.0, 2.5) - 4.0).abs() < 1e-5);
        assert!((time_from_rest(40.0, 10.0, 2.5) - 6.0).abs() < 1e-5);
        assert!((time_from_rest(5.0, 10.0, 2.5) - 2.0).abs() < 1e-5);
    }
}
