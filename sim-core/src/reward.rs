//! The rewards of an episode, every constant configurable (`[env.reward]`): the paper's, and a
//! route-progress reward that ranks outcomes as driving scores do.
//!
//! `kind = "paper"` (the default), the paper's eq. 4–8. Collision: r = r_c (−1) and the episode
//! ends; arrival (l < ε): r = +100 and it ends; otherwise r = β_v·r_v + β_l·r_l + β_w·r_w with
//! r_v = v/v0 − 1, r_l = 1 − l/l_prev, r_w = 1 − d/d0. The end-to-end variant has no r_w. Under it
//! standing still costs about 1 a step while a collision costs 1 once, so stopping behind a
//! stalled car and waiting returns far less than driving into it.
//!
//! `kind = "progress"`, after CaRL (Jaeger et al. 2025, "CaRL: Learning Scalable Planning
//! Policies with Simple Rewards": the reward is route progress scaled by soft penalties, and a
//! collision ends the episode; here the one soft penalty is subtracted) and Roach (Zhang et al. 2021, "End-to-End Urban Driving by Imitating a
//! Reinforcement Learning Coach": the collision penalty grows with the speed of impact). Per step
//! while driving, r = r_p + r_lane with r_p = min(Δs, v0·dt)/(v0·dt), Δs the route arc length
//! gained this step (negative going backwards; no gain for speed above v0), and, in the hybrid
//! variant only (it plays r_w's part), r_lane = −w_lane·max(0, |lateral| − z)/z, lateral the
//! offset from the planner's path and z a dead zone of about half a lane. A collision ends the
//! episode with `progress_collision` − `collision_per_speed`·v; arrival with `progress_arrival`.
//! Standing still earns nothing and costs nothing, so arriving beats stopping safely and
//! waiting, which beats crashing. It reads nothing the agent could not know (no hazard).
//!
//! A time-limit truncation is not a terminal state under either kind and costs nothing.

use serde::{Deserialize, Serialize};

use crate::config::error::ConfigError;
use crate::config::variant::Variant;

/// Which reward an environment computes (`[env.reward] kind`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RewardKind {
    /// The paper's eq. 4–8: speed, distance and waypoint terms; r_c and the arrival reward.
    #[default]
    Paper,
    /// Route progress per step, a lane penalty (hybrid), a speed-dependent collision penalty.
    Progress,
}

/// Reward constants. Defaults are the paper's ([`RewardConfig::paper`]); the `progress_*`,
/// `collision_per_speed` and `lane_*` fields are read by the `progress` kind only, and default to
/// its values, so that `kind = "progress"` alone selects [`RewardConfig::progress`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RewardConfig {
    /// Which reward: `paper` (the paper's equations 4–8) or `progress` (route progress, soft
    /// penalties, a collision penalty growing with speed).
    pub kind: RewardKind,
    /// `paper`: reward of a collision step, r_c.
    pub collision: f32,
    /// `paper`: reward of the arrival step.
    pub arrival: f32,
    /// Arrival radius ε around the destination, metres.
    pub arrival_radius: f32,
    /// Desired speed v0, km/h. `paper`: the speed term's v0; `progress`: the target speed, a step
    /// at v0 along the route earns 1 and a faster one no more.
    pub v0_kmh: f32,
    /// `paper`: waypoint distance scale d0, metres.
    pub d0: f32,
    /// `paper`: weight β_v of the speed term.
    pub beta_v: f32,
    /// `paper`: weight β_l of the progress term.
    pub beta_l: f32,
    /// `paper`: weight β_w of the waypoint term.
    pub beta_w: f32,
    /// If set, the per-step shaped reward (not collision or arrival) is clipped to ±this.
    pub clip: Option<f32>,
    /// `progress`: reward of a collision at standstill. A faster one costs `collision_per_speed`
    /// more per m/s.
    pub progress_collision: f32,
    /// `progress`: taken off the collision reward per m/s of ego speed at the collision.
    pub collision_per_speed: f32,
    /// `progress`: reward of the arrival step.
    pub progress_arrival: f32,
    /// `progress`: weight of the lane penalty per step, hybrid variant only.
    pub lane_weight: f32,
    /// `progress`: lateral offset from the planner's path that costs nothing, metres. Beyond it
    /// the lane penalty grows by `lane_weight` per dead zone's width.
    pub lane_dead_zone: f32,
}

impl RewardConfig {
    /// The paper's constants (eq. 4–8): r_c = −1, +100 on arrival within 5 m, v0 = 50 km/h,
    /// d0 = 8 m, every weight 1, no clipping. Presets that train "the paper's agent" start here.
    /// The `progress` kind's fields hold its defaults, unread by this kind.
    #[must_use]
    pub const fn paper() -> Self {
        Self {
            kind: RewardKind::Paper,
            collision: -1.0,
            arrival: 100.0,
            arrival_radius: 5.0,
            v0_kmh: 50.0,
            d0: 8.0,
            beta_v: 1.0,
            beta_l: 1.0,
            beta_w: 1.0,
            clip: None,
            progress_collision: PROGRESS_COLLISION,
            collision_per_speed: COLLISION_PER_SPEED,
            progress_arrival: PROGRESS_ARRIVAL,
            lane_weight: LANE_WEIGHT,
            lane_dead_zone: LANE_DEAD_ZONE,
        }
    }

    /// The `progress` kind with its defaults: a step at v0 (50 km/h) along the route earns 1; a
    /// collision at v m/s costs 10 + 2·v; arrival within 5 m earns 10; in the hybrid variant each
    /// step more than 1.75 m (half a lane) off the planner's path costs 0.2 per further 1.75 m.
    #[must_use]
    pub const fn progress() -> Self {
        Self { kind: RewardKind::Progress, ..Self::paper() }
    }
}

/// `progress`'s collision reward at standstill: a crash costs what about ten steps at v0 earn,
/// so that no progress made before it pays for it.
const PROGRESS_COLLISION: f32 = -10.0;
/// `progress`'s extra collision cost per m/s (Roach's speed-dependent penalty): a crash at v0
/// costs several times one at walking pace, so braking before an impact is worth it too.
const COLLISION_PER_SPEED: f32 = 2.0;
/// `progress`'s arrival reward: finishing is worth more than idling short of the goal, without
/// dwarfing the progress terms the way the paper's +100 does.
const PROGRESS_ARRIVAL: f32 = 10.0;
/// `progress`'s lane penalty weight: a pass in the other lane (one dead zone beyond it) costs
/// less than the progress it makes at detour speed, so passing beats waiting.
const LANE_WEIGHT: f32 = 0.2;
/// `progress`'s dead zone, metres: about half a lane, so drifting within the lane costs nothing.
const LANE_DEAD_ZONE: f32 = 1.75;

impl Default for RewardConfig {
    /// [`RewardConfig::paper`].
    fn default() -> Self {
        Self::paper()
    }
}

/// The reward terms of one step, for logging and tests. Terms of the other kind are 0.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct RewardTerms {
    /// `paper`: the speed term v/v0 − 1.
    pub r_v: f32,
    /// `paper`: the distance term 1 − l/l_prev.
    pub r_l: f32,
    /// `paper`: the waypoint term 1 − d/d0 (hybrid).
    pub r_w: f32,
    /// `progress`: route progress, min(Δs, v0·dt)/(v0·dt).
    pub r_p: f32,
    /// `progress`: the lane penalty, ≤ 0 (hybrid).
    pub r_lane: f32,
    pub total: f32,
}

/// How a step ended, as far as the reward is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Collision,
    Arrived,
    Driving,
}

/// What the reward reads of one step, measured after it (except `l_prev`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepMeasures {
    /// Ego speed, m/s.
    pub speed: f32,
    /// Straight-line distance to the destination after the step, metres.
    pub l: f32,
    /// The same before the step, metres.
    pub l_prev: f32,
    /// Distance to the closest waypoint of the planner's path, metres.
    pub d: f32,
    /// Route arc length gained this step, metres (negative going backwards).
    pub ds: f32,
    /// Signed lateral offset from the planner's path, metres.
    pub lateral: f32,
    /// The step's duration, seconds.
    pub dt: f32,
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

    /// The reward of one step.
    #[must_use]
    pub fn reward(&self, variant: Variant, outcome: Outcome, m: &StepMeasures) -> RewardTerms {
        match self.kind {
            RewardKind::Paper => self.paper_reward(variant, outcome, m),
            RewardKind::Progress => self.progress_reward(variant, outcome, m),
        }
    }

    fn paper_reward(&self, variant: Variant, outcome: Outcome, m: &StepMeasures) -> RewardTerms {
        match outcome {
            Outcome::Collision => RewardTerms { total: self.collision, ..RewardTerms::default() },
            Outcome::Arrived => RewardTerms { total: self.arrival, ..RewardTerms::default() },
            Outcome::Driving => {
                let r_v = m.speed / self.v0() - 1.0;
                let r_l = if m.l_prev > 0.0 { 1.0 - m.l / m.l_prev } else { 0.0 };
                let r_w = match variant {
                    Variant::Hybrid => 1.0 - m.d / self.d0,
                    Variant::EndToEnd => 0.0,
                };
                let total = self.clipped(self.beta_v * r_v + self.beta_l * r_l + self.beta_w * r_w);
                RewardTerms { r_v, r_l, r_w, total, ..RewardTerms::default() }
            }
        }
    }

    fn progress_reward(&self, variant: Variant, outcome: Outcome, m: &StepMeasures) -> RewardTerms {
        match outcome {
            Outcome::Collision => {
                RewardTerms { total: self.progress_collision - self.collision_per_speed * m.speed.abs(), ..RewardTerms::default() }
            }
            Outcome::Arrived => RewardTerms { total: self.progress_arrival, ..RewardTerms::default() },
            Outcome::Driving => {
                let target = self.v0() * m.dt;
                let r_p = m.ds.min(target) / target;
                let r_lane = match variant {
                    Variant::Hybrid => -self.lane_weight * (m.lateral.abs() - self.lane_dead_zone).max(0.0) / self.lane_dead_zone,
                    Variant::EndToEnd => 0.0,
                };
                RewardTerms { r_p, r_lane, total: self.clipped(r_p + r_lane), ..RewardTerms::default() }
            }
        }
    }

    fn clipped(&self, total: f32) -> f32 {
        match self.clip {
            Some(c) => total.clamp(-c, c),
            None => total,
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
            (self.progress_collision, "progress_collision"),
            (self.progress_arrival, "progress_arrival"),
        ] {
            if !x.is_finite() {
                return err(f, format!("{x} must be finite"));
            }
        }
        // Negative, these would reward crashing faster or leaving the path.
        for (x, f) in [(self.collision_per_speed, "collision_per_speed"), (self.lane_weight, "lane_weight")] {
            if !(x.is_finite() && x >= 0.0) {
                return err(f, format!("{x} must be a finite number >= 0"));
            }
        }
        for (x, f) in
            [(self.arrival_radius, "arrival_radius"), (self.v0_kmh, "v0_kmh"), (self.d0, "d0"), (self.lane_dead_zone, "lane_dead_zone")]
        {
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
    /// Route arc length covered in one 0.1 s step at v0.
    const AT_V0: f32 = V0 * 0.1;

    /// The paper's measurements: speed, l, l_prev and d (the rest unread by it).
    fn paper(speed: f32, l: f32, l_prev: f32, d: f32) -> StepMeasures {
        StepMeasures { speed, l, l_prev, d, ds: 0.0, lateral: 0.0, dt: 0.1 }
    }

    /// The progress kind's measurements: speed, Δs and lateral at 10 Hz, far from the goal.
    fn progress(speed: f32, ds: f32, lateral: f32) -> StepMeasures {
        StepMeasures { speed, l: 100.0, l_prev: 100.0, d: 3.0, ds, lateral, dt: 0.1 }
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-5
    }

    #[test]
    fn the_default_is_the_paper() {
        assert_eq!(RewardConfig::default(), RewardConfig::paper());
        assert_eq!(RewardConfig::paper().kind, RewardKind::Paper);
    }

    #[test]
    fn collision_and_arrival_override_the_shaped_terms() {
        let r = RewardConfig::paper();
        assert_eq!(r.reward(Variant::Hybrid, Outcome::Collision, &paper(V0, 10.0, 20.0, 0.0)).total, -1.0);
        assert_eq!(r.reward(Variant::EndToEnd, Outcome::Arrived, &paper(0.0, 4.0, 6.0, 7.0)).total, 100.0);
        assert!(r.arrived(4.99) && !r.arrived(5.0));
    }

    #[test]
    fn each_term_matches_the_paper() {
        let r = RewardConfig::paper();
        // At v0, not moving closer, on a waypoint: r_v = 0, r_l = 0, r_w = 1.
        let t = r.reward(Variant::Hybrid, Outcome::Driving, &paper(V0, 100.0, 100.0, 0.0));
        assert_eq!((t.r_v, t.r_l, t.r_w, t.total), (0.0, 0.0, 1.0, 1.0));
        assert_eq!((t.r_p, t.r_lane), (0.0, 0.0), "the progress kind's terms stay 0");
        // Standing still: r_v = −1. Halving l: r_l = 0.5. d = d0: r_w = 0. d = 2·d0: r_w = −1.
        let t = r.reward(Variant::Hybrid, Outcome::Driving, &paper(0.0, 50.0, 100.0, 8.0));
        assert_eq!((t.r_v, t.r_l, t.r_w), (-1.0, 0.5, 0.0));
        assert!((t.total + 0.5).abs() < 1e-6);
        assert_eq!(r.reward(Variant::Hybrid, Outcome::Driving, &paper(V0, 10.0, 10.0, 16.0)).r_w, -1.0);
        // Moving away: r_l negative.
        assert!((r.reward(Variant::Hybrid, Outcome::Driving, &paper(V0, 11.0, 10.0, 0.0)).r_l + 0.1).abs() < 1e-6);
    }

    #[test]
    fn end_to_end_has_no_waypoint_term_and_weights_apply() {
        let r = RewardConfig::paper();
        let t = r.reward(Variant::EndToEnd, Outcome::Driving, &paper(V0 / 2.0, 90.0, 100.0, 0.0));
        assert_eq!(t.r_w, 0.0);
        assert!((t.total - (-0.5 + 0.1)).abs() < 1e-6, "{t:?}");
        // β_v = β_l = 0 (and β_c unused when no collision): the reward is r_w alone.
        let mimic = RewardConfig { beta_v: 0.0, beta_l: 0.0, ..RewardConfig::paper() };
        assert_eq!(mimic.reward(Variant::Hybrid, Outcome::Driving, &paper(3.0, 90.0, 100.0, 2.0)).total, 0.75);
        let clipped = RewardConfig { clip: Some(0.5), ..RewardConfig::paper() };
        assert_eq!(clipped.reward(Variant::Hybrid, Outcome::Driving, &paper(V0, 10.0, 10.0, 0.0)).total, 0.5);
    }

    #[test]
    fn progress_earns_one_a_step_at_the_target_speed_and_nothing_more_above_it() {
        let r = RewardConfig::progress();
        let t = r.reward(Variant::Hybrid, Outcome::Driving, &progress(V0, AT_V0, 0.0));
        assert!(close(t.r_p, 1.0) && close(t.total, 1.0), "{t:?}");
        assert_eq!((t.r_v, t.r_l, t.r_w, t.r_lane), (0.0, 0.0, 0.0, 0.0), "the paper's terms stay 0");
        // Half the target's arc length: 0.5. Twice it: still 1 (capped). Standing still: 0.
        assert!(close(r.reward(Variant::Hybrid, Outcome::Driving, &progress(V0 / 2.0, AT_V0 / 2.0, 0.0)).r_p, 0.5));
        assert!(close(r.reward(Variant::Hybrid, Outcome::Driving, &progress(2.0 * V0, 2.0 * AT_V0, 0.0)).r_p, 1.0));
        assert_eq!(r.reward(Variant::Hybrid, Outcome::Driving, &progress(0.0, 0.0, 0.0)).total, 0.0);
        // Going backwards costs what it loses, uncapped.
        assert!(close(r.reward(Variant::Hybrid, Outcome::Driving, &progress(V0, -2.0 * AT_V0, 0.0)).r_p, -2.0));
        // The target is v0: at 25 km/h a step of v0's arc length earns 2 at most (capped at 1 there).
        let slow = RewardConfig { v0_kmh: 25.0, ..RewardConfig::progress() };
        assert!(close(slow.reward(Variant::Hybrid, Outcome::Driving, &progress(V0, AT_V0 / 2.0, 0.0)).r_p, 1.0));
    }

    #[test]
    fn progress_lane_penalty_starts_beyond_the_dead_zone_in_the_hybrid_variant_only() {
        let r = RewardConfig::progress();
        let lane = |variant, lateral| r.reward(variant, Outcome::Driving, &progress(V0, AT_V0, lateral));
        // Within the dead zone, on either side: nothing.
        assert_eq!(lane(Variant::Hybrid, 1.7).r_lane, 0.0);
        assert_eq!(lane(Variant::Hybrid, -1.75).r_lane, 0.0);
        // One dead zone beyond it (a lane over): −lane_weight; two: twice that.
        let t = lane(Variant::Hybrid, -2.0 * LANE_DEAD_ZONE);
        assert!(close(t.r_lane, -LANE_WEIGHT) && close(t.total, 1.0 - LANE_WEIGHT), "{t:?}");
        assert!(close(lane(Variant::Hybrid, 3.0 * LANE_DEAD_ZONE).r_lane, -2.0 * LANE_WEIGHT));
        // End to end: no lane term (it is the waypoint term, as r_w is).
        assert_eq!(lane(Variant::EndToEnd, 3.0 * LANE_DEAD_ZONE).r_lane, 0.0);
        // A pass in the other lane at a detour's 8 m/s still earns more than waiting (0).
        let pass = r.reward(Variant::Hybrid, Outcome::Driving, &progress(8.0, 0.8, 2.0 * LANE_DEAD_ZONE)).total;
        assert!(pass > 0.0, "{pass}");
    }

    #[test]
    fn progress_collision_costs_more_the_faster_and_arrival_earns_its_own_reward() {
        let r = RewardConfig::progress();
        let crash = |speed| r.reward(Variant::Hybrid, Outcome::Collision, &progress(speed, AT_V0, 0.0));
        assert_eq!(crash(0.0).total, PROGRESS_COLLISION);
        assert!(close(crash(V0).total, PROGRESS_COLLISION - COLLISION_PER_SPEED * V0));
        assert_eq!((crash(V0).r_p, crash(V0).r_lane), (0.0, 0.0), "a collision step earns no progress");
        let arrive = r.reward(Variant::EndToEnd, Outcome::Arrived, &progress(3.0, AT_V0, 0.0));
        assert_eq!(arrive.total, PROGRESS_ARRIVAL);
        // Clipping bounds the per-step terms only.
        let clipped = RewardConfig { clip: Some(0.5), ..RewardConfig::progress() };
        assert_eq!(clipped.reward(Variant::Hybrid, Outcome::Driving, &progress(V0, AT_V0, 0.0)).total, 0.5);
        assert_eq!(clipped.reward(Variant::Hybrid, Outcome::Collision, &progress(0.0, 0.0, 0.0)).total, PROGRESS_COLLISION);
    }

    #[test]
    fn progress_kind_alone_selects_the_progress_preset_and_paper_configs_parse_unchanged() {
        let parse = |s: &str| toml::from_str::<RewardConfig>(s).unwrap();
        assert_eq!(parse("kind = \"progress\""), RewardConfig::progress());
        assert_eq!(parse("beta_w = 1.0\nclip = 2.0"), RewardConfig { clip: Some(2.0), ..RewardConfig::paper() });
        assert_eq!(parse("kind = \"paper\""), RewardConfig::paper());
    }

    #[test]
    fn validate_names_the_new_fields() {
        let field = |r: RewardConfig| r.validate().unwrap_err().field;
        assert!(RewardConfig::progress().validate().is_ok());
        let p = RewardConfig::progress;
        assert_eq!(field(RewardConfig { progress_collision: f32::NAN, ..p() }), "reward.progress_collision");
        assert_eq!(field(RewardConfig { progress_arrival: f32::INFINITY, ..p() }), "reward.progress_arrival");
        assert_eq!(field(RewardConfig { collision_per_speed: f32::NAN, ..p() }), "reward.collision_per_speed");
        assert_eq!(field(RewardConfig { collision_per_speed: -1.0, ..p() }), "reward.collision_per_speed");
        assert_eq!(field(RewardConfig { lane_weight: f32::NEG_INFINITY, ..p() }), "reward.lane_weight");
        assert_eq!(field(RewardConfig { lane_dead_zone: 0.0, ..p() }), "reward.lane_dead_zone");
        assert_eq!(field(RewardConfig { lane_dead_zone: f32::NAN, ..p() }), "reward.lane_dead_zone");
    }
}
