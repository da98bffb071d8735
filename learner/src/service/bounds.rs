//! What an actor's numbers can physically be in this run, from its `[env]`: the speed the
//! vehicle can reach, how far from its route it can get, the angles of the path features, and
//! the rewards the configured reward (with its clip) can produce, the vector sensor's [−1, 1]. A batch beyond them
//! (`validate.rs`) is refused: no simulator sends 1e30 m/s, a raw client or a broken actor does.
//! Margins are generous: the bounds are there to refuse the impossible, not the unusual.

use sim_core::config::{EnvConfig, Variant};
use sim_core::reward::RewardKind;

/// Margins: a bound is `FACTOR × the physical limit + SLACK` (in the value's unit).
const FACTOR: f32 = 2.0;
const SLACK: f32 = 1.0;

/// The run's bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// |speed|, m/s: 2 × `env.vehicle.max_speed` + 1.
    pub speed: f32,
    /// |d| and |lateral path feature|, metres: 2 × (the longest route + the farthest the
    /// vehicle drives in the longest episode at top speed) + 1.
    pub distance: f32,
    /// |path angle|, radians: π (they are wrapped) + 0.01.
    pub angle: f32,
    /// The per-step reward's range (collision, arrival and the shaped terms, clipped when
    /// `env.reward.clip` is set), widened by the margins.
    pub reward: (f32, f32),
    /// |episode return|: the longest episode's steps × the largest |reward|.
    pub episode_return: f32,
    /// |a vector sensor value|: the sensor clamps every value to [−1, 1] (`sim_core::sensor`),
    /// so no margin: anything beyond is not the sensor's.
    pub vector: f32,
}

impl Bounds {
    #[must_use]
    pub fn of(env: &EnvConfig) -> Self {
        let vmax = env.vehicle.max_speed.abs();
        let steps = env.time_limit.max(env.eval_time_limit) as f32;
        let reach = env.route_length_max.abs() + steps * env.dt.abs() * vmax;
        let distance = FACTOR * reach + SLACK;
        let r = &env.reward;
        let scaled = |beta: f32, (lo, hi): (f32, f32)| if beta >= 0.0 { (beta * lo, beta * hi) } else { (beta * hi, beta * lo) };
        let clip = |(lo, hi): (f32, f32)| r.clip.map_or((lo, hi), |c| (lo.max(-c), hi.min(c)));
        // The driving step's shaped reward, the collision's and the arrival's, each an interval
        // (sim_core::reward).
        let (shaped, collision, arrival) = match r.kind {
            RewardKind::Paper => {
                let r_v = (-1.0, vmax / r.v0() - 1.0);
                // Progress 1 − l/l_prev: at most 1; at least −(one step's travel)/(the arrival
                // radius, below which the episode ends).
                let r_l = (-(vmax * env.dt.abs()) / r.arrival_radius, 1.0);
                let r_w = match env.variant {
                    Variant::Hybrid => (1.0 - distance / r.d0, 1.0),
                    Variant::EndToEnd => (0.0, 0.0),
                };
                let terms = [scaled(r.beta_v, r_v), scaled(r.beta_l, r_l), scaled(r.beta_w, r_w)];
                (clip(terms.iter().fold((0.0, 0.0), |acc, t| (acc.0 + t.0, acc.1 + t.1))), (r.collision, r.collision), r.arrival)
            }
            RewardKind::Progress => {
                // Progress min(ds, v0·dt)/(v0·dt): at most 1, at least a step backwards at top speed.
                let r_p = (-vmax / r.v0(), 1.0);
                let r_lane = match env.variant {
                    Variant::Hybrid => (-r.lane_weight * (distance - r.lane_dead_zone).max(0.0) / r.lane_dead_zone, 0.0),
                    Variant::EndToEnd => (0.0, 0.0),
                };
                // A collision costs more the faster it is: at most top speed.
                let collision = (r.progress_collision - r.collision_per_speed * vmax, r.progress_collision);
                (clip((r_p.0 + r_lane.0, r_p.1 + r_lane.1)), collision, r.progress_arrival)
            }
        };
        let lo = shaped.0.min(collision.0).min(arrival);
        let hi = shaped.1.max(collision.1).max(arrival);
        let widen = |x: f32| x.abs() * (FACTOR - 1.0) + SLACK;
        let reward = (lo - widen(lo), hi + widen(hi));
        Self {
            speed: FACTOR * vmax + SLACK,
            distance,
            angle: std::f32::consts::PI + 0.01,
            reward,
            episode_return: (steps + 1.0) * reward.0.abs().max(reward.1.abs()),
            vector: 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default run: 30 m/s top speed, routes up to 150 m, 300 steps of 0.1 s, the paper's
    /// reward (−1 on collision, +100 on arrival, no clip).
    #[test]
    fn the_default_runs_bounds() {
        let b = Bounds::of(&EnvConfig::default());
        assert_eq!(b.speed, 61.0);
        assert_eq!(b.distance, 2.0 * (150.0 + 300.0 * 0.1 * 30.0) + 1.0);
        // Arrival's +100 is the top; the waypoint term at the distance bound the bottom.
        assert_eq!(b.reward.1, 201.0);
        assert!(b.reward.0 < -100.0 && b.reward.0 > -2000.0, "{:?}", b.reward);
        let mut clipped = EnvConfig::default();
        clipped.reward.clip = Some(1.0);
        clipped.reward.arrival = 1.0;
        let b = Bounds::of(&clipped);
        assert_eq!(b.reward, (-3.0, 3.0));
    }

    /// Every preset's extreme rewards are within its bounds: a collision at top speed under the
    /// progress reward (end-to-end: no lane term to widen the bound) was once refused.
    #[test]
    fn every_presets_extreme_rewards_are_within_its_bounds() {
        use sim_core::reward::{Outcome, StepMeasures};
        for name in agent::presets::PRESETS.iter().map(|p| p.0) {
            let cfg = agent::config::RunConfig::preset(name).unwrap().env;
            let b = Bounds::of(&cfg);
            let vmax = cfg.vehicle.max_speed;
            let fast = StepMeasures { speed: vmax, ..StepMeasures::default() };
            let backwards = StepMeasures { speed: vmax, ds: -vmax * cfg.dt, dt: cfg.dt, ..StepMeasures::default() };
            for (outcome, m) in [(Outcome::Collision, &fast), (Outcome::Arrived, &fast), (Outcome::Driving, &backwards)] {
                let reward = cfg.reward.reward(cfg.variant, outcome, m).total;
                assert!((b.reward.0..=b.reward.1).contains(&reward), "{name}: {outcome:?} gives {reward}, beyond {:?}", b.reward);
            }
        }
    }
}
