//! Path features: the planner's route as the hybrid agent observes it, beyond the paper's d
//! (which has no sign and no direction). Part of the observation (`Env::path_features`), so part
//! of what trained checkpoints expect: every constant here is frozen.

use crate::math::{heading_of, wrap_angle};
use crate::route::{Route, Tracking};
use crate::vehicle::VehicleState;

/// How many numbers [`path_features`] gives.
pub const PATH_FEATURES: usize = 3;

/// Route distance ahead of the ego vehicle whose direction is the far path feature, metres: far
/// enough to see a junction's turn before the vehicle must brake for it.
const FAR_PREVIEW: f32 = 25.0;

/// Route distance ahead of the ego vehicle whose direction is the near path feature at speed `v`
/// (m/s), metres: 0.5 s of travel plus 3 m, within 4–12 m.
///
/// The same numbers as the reference driver's pure-pursuit lookahead (`expert::lookahead`) when
/// path features were introduced, but defined here on purpose: checkpoints were trained on these
/// inputs, so retuning the driver must not change what the network sees.
#[must_use]
pub fn near_preview(v: f32) -> f32 {
    (0.5 * v + 3.0).clamp(4.0, 12.0)
}

/// The path features of a vehicle `ego` on `route`, where the route tracker measured `tracking`:
/// the signed lateral offset from the route's centre line (metres, positive to the left), the
/// angle from the ego heading to the route point [`near_preview`] ahead (radians, positive to the
/// left), and the same angle to the route point 25 m ahead, which previews turns and curves.
#[must_use]
pub fn path_features(route: &Route, tracking: &Tracking, ego: &VehicleState) -> [f32; PATH_FEATURES] {
    path_features_along(|s| route.path.point_at(s), tracking, ego)
}

/// The same features along any path given by its point at each route arc length (a planner's
/// bent route); `tracking` measured against it.
#[must_use]
pub fn path_features_along(point_at: impl Fn(f32) -> crate::math::Vec2, tracking: &Tracking, ego: &VehicleState) -> [f32; PATH_FEATURES] {
    let s = tracking.s;
    let angle_to = |ahead: f32| {
        let to = point_at(s + ahead) - ego.pos;
        if to.length_squared() < 1e-6 { 0.0 } else { wrap_angle(heading_of(to) - ego.heading) }
    };
    [tracking.lateral, angle_to(near_preview(ego.speed)), angle_to(FAR_PREVIEW)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec2;
    use crate::polyline::Polyline;

    #[test]
    fn near_preview_is_half_a_second_plus_three_metres_within_4_to_12() {
        // The definition the first path-feature checkpoints were trained with (0.5·v + 3, clamped).
        assert_eq!(near_preview(0.0), 4.0);
        assert_eq!(near_preview(10.0), 8.0);
        assert_eq!(near_preview(30.0), 12.0);
    }

    #[test]
    fn features_of_a_vehicle_right_of_a_straight_route() {
        // Route along +x; the vehicle 1 m to its right at x = 10, heading along it at 10 m/s.
        // Near point: 8 m ahead, (18, 0), seen at atan(1/8); far point (35, 0) at atan(1/25).
        let route = Route {
            path: Polyline::new([Vec2::ZERO, Vec2::new(100.0, 0.0)]).expect("two points"),
            waypoints: vec![Vec2::ZERO],
            lanes: vec![(0, 0.0)],
            cost: 0.0,
        };
        let tracking = Tracking { d: 1.0, s: 10.0, lateral: -1.0 };
        let ego = VehicleState { speed: 10.0, ..VehicleState::at_rest(Vec2::new(10.0, -1.0), 0.0) };
        let [lateral, near, far] = path_features(&route, &tracking, &ego);
        assert_eq!(lateral, -1.0);
        assert!((near - (1.0f32 / 8.0).atan()).abs() < 1e-6, "{near}");
        assert!((far - (1.0f32 / 25.0).atan()).abs() < 1e-6, "{far}");
    }
}
