//! The kinematic bicycle model and the mapping from (throttle, brake, steer) to it.

use serde::{Deserialize, Serialize};

use crate::math::{Vec2, atan, cos, dir, sin, tan, wrap_angle};

/// A control command. Values outside the ranges are clamped.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Action {
    /// 0 to 1.
    pub throttle: f32,
    /// 0 to 1.
    pub brake: f32,
    /// −1 (full left) to 1 (full right), the sign convention of CARLA and the paper's code.
    pub steer: f32,
}

impl Action {
    #[must_use]
    pub const fn new(throttle: f32, brake: f32, steer: f32) -> Self {
        Self { throttle, brake, steer }
    }

    /// The action with each component clamped to its range (NaN becomes 0).
    #[must_use]
    pub fn clamped(self) -> Self {
        let c = |x: f32, lo: f32, hi: f32| if x.is_nan() { 0.0 } else { x.clamp(lo, hi) };
        Self { throttle: c(self.throttle, 0.0, 1.0), brake: c(self.brake, 0.0, 1.0), steer: c(self.steer, -1.0, 1.0) }
    }
}

/// Physical limits of a vehicle. Defaults: a mid-size car.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleParams {
    /// Body length, metres.
    pub length: f32,
    /// Body width, metres.
    pub width: f32,
    /// Distance between axles, metres.
    pub wheelbase: f32,
    /// Acceleration at full throttle from standstill, m/s². It falls linearly to 0 at `max_speed`.
    pub max_accel: f32,
    /// Deceleration at full brake, m/s².
    pub max_brake: f32,
    /// Deceleration when coasting (rolling resistance and drag), m/s².
    pub coast_decel: f32,
    /// Top speed, m/s.
    pub max_speed: f32,
    /// Front-wheel angle at full lock when slow, radians.
    pub max_steer: f32,
    /// Speed at which the usable lock has halved, m/s. Steering is gentler when fast, as in driving
    /// games and CARLA, so that a full-lock command is a lane change, not a spin.
    pub steer_halving_speed: f32,
    /// How fast the wheels turn toward the commanded angle, radians per second.
    pub steer_rate: f32,
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self {
            length: 4.5,
            width: 1.9,
            wheelbase: 2.7,
            max_accel: 3.5,
            max_brake: 8.0,
            coast_decel: 0.3,
            max_speed: 30.0,
            max_steer: 0.6,
            steer_halving_speed: 10.0,
            steer_rate: 2.0,
        }
    }
}

impl VehicleParams {
    /// The usable wheel angle at full lock at speed `v`.
    #[must_use]
    pub fn steer_limit(&self, v: f32) -> f32 {
        self.max_steer / (1.0 + v / self.steer_halving_speed)
    }

    /// Half the body's length and width.
    #[must_use]
    pub fn half_extents(&self) -> Vec2 {
        Vec2::new(self.length / 2.0, self.width / 2.0)
    }
}

/// State of a vehicle driven by the bicycle model. `pos` is the body centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleState {
    pub pos: Vec2,
    /// Radians, counter-clockwise from +x.
    pub heading: f32,
    /// m/s, never negative (no reverse gear).
    pub speed: f32,
    /// Current front-wheel angle, radians, positive to the left.
    pub steer: f32,
}

impl VehicleState {
    /// A vehicle at rest.
    #[must_use]
    pub fn at_rest(pos: Vec2, heading: f32) -> Self {
        Self { pos, heading, speed: 0.0, steer: 0.0 }
    }

    /// Advances the state by `dt` seconds under `action` (semi-implicit Euler, reference point at
    /// the body centre).
    pub fn step(&mut self, p: &VehicleParams, action: Action, dt: f32) {
        let a = action.clamped();
        let drive = a.throttle * p.max_accel * (1.0 - self.speed / p.max_speed).max(0.0);
        let resist = if self.speed > 0.0 { p.coast_decel + a.brake * p.max_brake } else { 0.0 };
        self.speed = (self.speed + (drive - resist) * dt).clamp(0.0, p.max_speed);

        // Steer sign: the command's right (+) is a negative (clockwise) wheel angle.
        let target = -a.steer * p.steer_limit(self.speed);
        let max_change = p.steer_rate * dt;
        self.steer += (target - self.steer).clamp(-max_change, max_change);

        // Slip angle at the centre of mass (halfway between the axles).
        let beta = atan(0.5 * tan(self.steer));
        let yaw_rate = self.speed * cos(beta) * tan(self.steer) / p.wheelbase;
        self.heading = wrap_angle(self.heading + yaw_rate * dt);
        let v = Vec2::new(cos(self.heading + beta), sin(self.heading + beta)) * self.speed;
        self.pos += v * dt;
    }

    /// The body's forward unit vector.
    #[must_use]
    pub fn forward(&self) -> Vec2 {
        dir(self.heading)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_throttle_accelerates_and_brake_stops() {
        let p = VehicleParams::default();
        let mut v = VehicleState::at_rest(Vec2::ZERO, 0.0);
        for _ in 0..10 {
            v.step(&p, Action::new(1.0, 0.0, 0.0), 0.1);
        }
        // ~3.5 m/s² minus drag over 1 s, a little less as speed rises.
        assert!(v.speed > 2.5 && v.speed < 3.5, "{}", v.speed);
        assert!(v.pos.x > 1.0 && v.pos.y == 0.0);
        for _ in 0..10 {
            v.step(&p, Action::new(0.0, 1.0, 0.0), 0.1);
        }
        assert_eq!(v.speed, 0.0);
    }

    #[test]
    fn negative_steer_turns_left() {
        let p = VehicleParams::default();
        let mut v = VehicleState { speed: 5.0, ..VehicleState::at_rest(Vec2::ZERO, 0.0) };
        for _ in 0..10 {
            v.step(&p, Action::new(0.3, 0.0, -1.0), 0.1);
        }
        assert!(v.heading > 0.1 && v.pos.y > 0.0, "{v:?}");
    }

    #[test]
    fn out_of_range_actions_are_clamped() {
        let a = Action::new(2.0, -1.0, f32::NAN).clamped();
        assert_eq!(a, Action::new(1.0, 0.0, 0.0));
    }
}
