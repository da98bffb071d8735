//! The paper's reward (eq. 4–8), every constant configurable.
//!
//! collision: r = r_c (−1) and the episode ends; arrival (l < ε): r = +100 and it ends; otherwise
//! r = β_v·r_v + β_l·r_l + β_w·r_w with r_v = v/v0 − 1, r_l = 1 − l/l_prev, r_w = 1 − d/d0.
//! The end-to-end variant has no r_w.

use serde::{Deserialize, Serialize};

use crate::config::error::ConfigError;
use crate::config::variant::Variant;

/// Reward constants. Defaults are the paper's ([`RewardConfig::paper`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RewardConfig {
    /// Reward of a collision step, r_c.
    pub collision: f32,
    /// Reward of the arrival step.
    pub arrival: f32,
    /// Arrival radius ε around the destination, metres.
    pub arrival_radius: f32,
    /// Desired speed v0, km/h.
    pub v0_kmh: f32,
    /// Waypoint distance scale d0, metres.
    pub d0: f32,
    /// Weight β_v of the speed term.
    pub beta_v: f32,
    /// Weight β_l of the progress term.
    pub beta_l: f32,
    /// Weight β_w of the waypoint term.
    pub beta_w: f32,
    /// If set, the per-step shaped reward (not collision or arrival) is clipped to ±this.
    pub clip: Option<f32>,
}

impl RewardConfig {
    /// The paper's constants (eq. 4–8): r_c = −1, +100 on arrival within 5 m, v0 = 50 km/h,
    /// d0 = 8 m, every weight 1, no clipping. Presets that train "the paper's agent" start here.
    #[must_use]
    pub const fn paper() -> Self {
        Self {
            collision: -1.0,
            arrival: 100.0,
            arrival_radius: 5.0,
            v0_kmh: 50.0,
            d0: 8.0,
            beta_v: 1.0,
            beta_l: 1.0,
            beta_w: 1.0,
            clip: None,
        }
    }
}

impl Default for RewardConfig {
    /// [`RewardConfig::paper`].
    fn default() -> Self {
        Self::paper()
    }
}

/// The reward terms of one step, for logging and tests.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct RewardTerms {
    pub r_v: f32,
    pub r_l: f32,
    pub r_w: f32,
    pub total: f32,
}

/// How a step ended, as far as the reward is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Collision,
    Arrived,
    Driving,
}

impl RewardConfig {
    /// v0 in m/s.
    #[must_use]
    pub fn v0(&self) -> f32 {
        self.v0_kmh / 3.6
    }

    /// Whether the vehicle `l` metres from its destination has arrived.
    #[must_use]
    pub fn arrived(&self, l: f32) -> bool {
        l < self.arrival_radius
    }

    /// The reward of one step. `speed` in m/s, `l` and `l_prev` the distances to the destination
    /// after and before the step, `d` the distance to the closest waypoint.
    #[must_use]
    pub fn reward(&self, variant: Variant, outcome: Outcome, speed: f32, l: f32, l_prev: f32, d: f32) -> RewardTerms {
        match outcome {
            Outcome::Collision => RewardTerms { total: self.collision, ..RewardTerms::default() },
            Outcome::Arrived => RewardTerms { total: self.arrival, ..RewardTerms::default() },
            Outcome::Driving => {
                let r_v = speed / self.v0() - 1.0;
                let r_l = if l_prev > 0.0 { 1.0 - l / l_prev } else { 0.0 };
                let r_w = match variant {
                    Variant::Hybrid => 1.0 - d / self.d0,
                    Variant::EndToEnd => 0.0,
                };
                let mut total = self.beta_v * r_v + self.beta_l * r_l + self.beta_w * r_w;
                if let Some(c) = self.clip {
                    total = total.clamp(-c, c);
                }
                RewardTerms { r_v, r_l, r_w, total }
            }
        }
    }

    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let err = |field: &str, message: String| Err(ConfigError { field: format!("reward.{field}"), message });
        for (x, f) in [
            (self.collision, "collision"),
            (self.arrival, "arrival"),
            (self.beta_v, "beta_v"),
            (self.beta_l, "beta_l"),
            (self.beta_w, "beta_w"),
        ] {
            if !x.is_finite() {
                return err(f, format!("{x} must be finite"));
            }
        }
        for (x, f) in [(self.arrival_radius, "arrival_radius"), (self.v0_kmh, "v0_kmh"), (self.d0, "d0")] {
            if !(x.is_finite() && x > 0.0) {
                return err(f, format!("{x} must be a finite number > 0"));
            }
        }
        if let Some(c) = self.clip
            && !(c.is_finite() && c > 0.0)
        {
            return err("clip", format!("{c} must be a finite number > 0"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const V0: f32 = 50.0 / 3.6;

    #[test]
    fn the_default_is_the_paper() {
        assert_eq!(RewardConfig::default(), RewardConfig::paper());
    }

    #[test]
    fn collision_and_arrival_override_the_shaped_terms() {
        let r = RewardConfig::paper();
        assert_eq!(r.reward(Variant::Hybrid, Outcome::Collision, V0, 10.0, 20.0, 0.0).total, -1.0);
        assert_eq!(r.reward(Variant::EndToEnd, Outcome::Arrived, 0.0, 4.0, 6.0, 7.0).total, 100.0);
        assert!(r.arrived(4.99) && !r.arrived(5.0));
    }

    #[test]
    fn each_term_matches_the_paper() {
        let r = RewardConfig::paper();
        // At v0, not moving closer, on a waypoint: r_v = 0, r_l = 0, r_w = 1.
        let t = r.reward(Variant::Hybrid, Outcome::Driving, V0, 100.0, 100.0, 0.0);
        assert_eq!((t.r_v, t.r_l, t.r_w, t.total), (0.0, 0.0, 1.0, 1.0));
        // Standing still: r_v = −1. Halving l: r_l = 0.5. d = d0: r_w = 0. d = 2·d0: r_w = −1.
        let t = r.reward(Variant::Hybrid, Outcome::Driving, 0.0, 50.0, 100.0, 8.0);
        assert_eq!((t.r_v, t.r_l, t.r_w), (-1.0, 0.5, 0.0));
        assert!((t.total + 0.5).abs() < 1e-6);
        assert_eq!(r.reward(Variant::Hybrid, Outcome::Driving, V0, 10.0, 10.0, 16.0).r_w, -1.0);
        // Moving away: r_l negative.
        assert!((r.reward(Variant::Hybrid, Outcome::Driving, V0, 11.0, 10.0, 0.0).r_l + 0.1).abs() < 1e-6);
    }

    #[test]
    fn end_to_end_has_no_waypoint_term_and_weights_apply() {
        let r = RewardConfig::paper();
        let t = r.reward(Variant::EndToEnd, Outcome::Driving, V0 / 2.0, 90.0, 100.0, 0.0);
        assert_eq!(t.r_w, 0.0);
        assert!((t.total - (-0.5 + 0.1)).abs() < 1e-6, "{t:?}");
        // β_v = β_l = 0 (and β_c unused when no collision): the reward is r_w alone.
        let mimic = RewardConfig { beta_v: 0.0, beta_l: 0.0, ..RewardConfig::paper() };
        assert_eq!(mimic.reward(Variant::Hybrid, Outcome::Driving, 3.0, 90.0, 100.0, 2.0).total, 0.75);
        let clipped = RewardConfig { clip: Some(0.5), ..RewardConfig::paper() };
        assert_eq!(clipped.reward(Variant::Hybrid, Outcome::Driving, V0, 10.0, 10.0, 0.0).total, 0.5);
    }
}
