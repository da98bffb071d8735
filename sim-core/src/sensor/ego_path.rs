//! The ego's own state and, for the hybrid agent, the planner's path: the first segments of the
//! vector.

use crate::math::{Vec2, cross};
use crate::path_features::PATH_FEATURES;
use crate::vehicle::{VehicleParams, VehicleState};

/// A lane's width, the scale of the lateral offset, metres.
pub const LANE_WIDTH: f32 = 3.5;

/// The planner's path as the sensor reads it (hybrid only).
pub struct PathInput<'a> {
    /// The planner's tracking d (`Env::planned_tracking`), metres.
    pub d: f32,
    /// `Env::path_features`: lateral offset (m), near and far heading angles (rad).
    pub features: [f32; PATH_FEATURES],
    /// The ego's arc length along the route, metres.
    pub ego_s: f32,
    pub route_length: f32,
    /// Waypoint spacing along the route, metres.
    pub spacing: f32,
    /// The planner's path at a route arc length (`Env::planned_point`).
    pub point_at: &'a dyn Fn(f32) -> Vec2,
}

impl std::fmt::Debug for PathInput<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PathInput")
            .field("d", &self.d)
            .field("features", &self.features)
            .field("ego_s", &self.ego_s)
            .field("route_length", &self.route_length)
            .field("spacing", &self.spacing)
            .finish_non_exhaustive()
    }
}

/// Writes the ego's speed, front-wheel angle and longitudinal acceleration (from `prev_speed`
/// over `dt`) into `out` (3 values).
pub fn write_ego(out: &mut [f32], ego: &VehicleState, vehicle: &VehicleParams, prev_speed: f32, dt: f32) {
    let accel = (ego.speed - prev_speed) / dt;
    out[0] = ego.speed / vehicle.max_speed;
    out[1] = ego.steer / vehicle.max_steer;
    out[2] = accel / vehicle.max_accel.max(vehicle.max_brake);
}

/// Writes d, the path features and the next `out_waypoints.len() / 2` waypoints of the planner's
/// path in the ego's frame (x ahead, y left, over `range`).
pub fn write_path(out_path: &mut [f32], out_waypoints: &mut [f32], path: &PathInput, d0: f32, ego: &VehicleState, range: f32) {
    let [lateral, near, far] = path.features;
    let pi = std::f32::consts::PI;
    out_path.copy_from_slice(&[path.d / d0, lateral / LANE_WIDTH, near / pi, far / pi]);
    let axis = crate::math::dir(ego.heading);
    let next = (path.ego_s / path.spacing).floor() + 1.0;
    for (k, w) in out_waypoints.chunks_exact_mut(2).enumerate() {
        let s = ((next + k as f32) * path.spacing).min(path.route_length);
        let v = (path.point_at)(s) - ego.pos;
        w.copy_from_slice(&[v.dot(axis) / range, cross(axis, v) / range]);
    }
}
