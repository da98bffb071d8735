//! The cut-in car's speed (after scenario_runner's `cut_in`): it drives in the adjacent
//! same-direction lane ahead of the ego, slowly while the ego is far behind, faster as the ego
//! closes on it, and at `SLOWER` × the ego's speed for the last `CLOSING` metres before the ego's
//! front is `cut_in_gap` behind its rear (measured along the route), where it changes into the
//! ego's lane: the ego closes on it at (1 − `SLOWER`) × its speed, from a short gap.

/// The cut-in car's speed is this fraction of the ego's while the ego closes the last metres on it
/// and while it changes lanes.
pub const SLOWER: f32 = 0.7;
/// It drives at `SLOWER` × the ego's speed from this many metres more than its gap on.
pub const CLOSING: f32 = 8.0;
/// Before that, `RAMP` m/s slower per metre further ahead (so that it reaches `SLOWER` × the
/// ego's speed within its acceleration as the ego closes), 1/s.
pub const RAMP: f32 = 0.2;
/// The slowest it drives, m/s.
pub const MIN_SPEED: f32 = 2.0;
/// Its acceleration and braking toward the speed it wants, m/s².
pub const ACCEL: f32 = 3.5;
/// How far ahead of the ego along the route its position is looked for, metres.
pub const WINDOW: f32 = 100.0;

/// The speed the cut-in car wants, m/s, while its rear is `ahead` metres ahead of the ego's front
/// (bumper to bumper along the route) and it changes lanes at `gap`: `SLOWER` × `ego_speed` from
/// `gap + CLOSING` on, `RAMP` m/s less per metre further, within `MIN_SPEED` and `limit`.
#[must_use]
pub fn wanted_speed(ahead: f32, gap: f32, ego_speed: f32, limit: f32) -> f32 {
    let further = (ahead - gap - CLOSING).max(0.0);
    (ego_speed * SLOWER - RAMP * further).clamp(MIN_SPEED.min(limit), limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slower_than_the_ego_as_it_closes_slowest_while_it_is_far() {
        // Within the last CLOSING metres: 0.7 × the ego's speed.
        assert!((wanted_speed(8.0 + CLOSING - 0.1, 8.0, 10.0, 14.0) - 10.0 * SLOWER).abs() < 1e-5);
        assert!((wanted_speed(8.0, 8.0, 10.0, 14.0) - 10.0 * SLOWER).abs() < 1e-5);
        // 10 m further: RAMP × 10 slower.
        assert!((wanted_speed(8.0 + CLOSING + 10.0, 8.0, 10.0, 14.0) - (10.0 * SLOWER - 10.0 * RAMP)).abs() < 1e-5);
        // Far off, or with the ego at rest: the slowest.
        assert_eq!(wanted_speed(80.0, 8.0, 10.0, 14.0), MIN_SPEED);
        assert_eq!(wanted_speed(8.0, 8.0, 0.0, 14.0), MIN_SPEED);
        // Never above the lane's limit.
        assert_eq!(wanted_speed(8.0, 8.0, 30.0, 14.0), 14.0);
    }
}
