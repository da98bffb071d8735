//! Discrete action sets: the DQN picks an index, the environment receives (throttle, brake, steer).
//!
//! `paper6` is the paper code's six, whose brake (0.1) decelerates at about 1.1 m/s² with the
//! default vehicle; `paper12` the seed code's earlier twelve; `full15`, `full21` and `full27`
//! full-authority sets: five, seven or nine steering values × {full throttle, coast, full brake},
//! so that the agent can brake at the vehicle's limit, roll, and brake while steering. How much
//! of the baselines' driving each set keeps is measured in docs/EVALUATION.md. [`ActionSet::nearest`] maps a continuous
//! control to a set's action (`actor eval --quantise`, docs/EVALUATION.md).

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::vehicle::Action;

/// A named set of discrete actions (`[agent] action_set`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionSet {
    /// The paper code's six: forward, forward-left, forward-right, brake, brake-left, brake-right.
    #[default]
    Paper6,
    /// The seed code's earlier twelve: throttle 0.3/0.6/1.0; steer ±0.3/±0.6/±1.0 at throttle
    /// 0.7; brake 0.3/0.6/1.0.
    Paper12,
    /// Full authority: steer −1, −0.35, 0, 0.35, 1, each with full throttle, coast or full brake.
    Full15,
    /// Full authority with finer steering: −1, −0.5, −0.2, 0, 0.2, 0.5, 1, each with full throttle,
    /// coast or full brake.
    Full21,
    /// Full authority with finer steering still: −1, −0.6, −0.3, −0.1, 0, 0.1, 0.3, 0.6, 1, each
    /// with full throttle, coast or full brake.
    Full27,
}

const PAPER6: [Action; 6] = [
    Action::new(1.0, 0.0, 0.0),
    Action::new(1.0, 0.0, -1.0),
    Action::new(1.0, 0.0, 1.0),
    Action::new(0.0, 0.1, 0.0),
    Action::new(0.0, 0.1, -0.1),
    Action::new(0.0, 0.1, 0.1),
];

const PAPER12: [Action; 12] = [
    Action::new(0.3, 0.0, 0.0),
    Action::new(0.6, 0.0, 0.0),
    Action::new(1.0, 0.0, 0.0),
    Action::new(0.7, 0.0, -0.3),
    Action::new(0.7, 0.0, 0.3),
    Action::new(0.7, 0.0, -0.6),
    Action::new(0.7, 0.0, 0.6),
    Action::new(0.7, 0.0, -1.0),
    Action::new(0.7, 0.0, 1.0),
    Action::new(0.0, 0.3, 0.0),
    Action::new(0.0, 0.6, 0.0),
    Action::new(0.0, 1.0, 0.0),
];

/// Steering of the full-authority set: fine near the centre for lane keeping, full lock for
/// junctions (the usable lock shrinks with speed, `VehicleParams::steer_limit`).
const FULL_STEER: [f32; 5] = [-1.0, -0.35, 0.0, 0.35, 1.0];

const FULL15: [Action; 15] = full_authority(FULL_STEER);
const FULL21: [Action; 21] = full_authority([-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0]);
const FULL27: [Action; 27] = full_authority([-1.0, -0.6, -0.3, -0.1, 0.0, 0.1, 0.3, 0.6, 1.0]);

/// Every steering value with full throttle, then coasting, then full brake.
const fn full_authority<const S: usize, const N: usize>(steer: [f32; S]) -> [Action; N] {
    assert!(N == 3 * S, "three longitudinal choices per steering value");
    let mut out = [Action::new(0.0, 0.0, 0.0); N];
    let mut i = 0;
    while i < S {
        out[i] = Action::new(1.0, 0.0, steer[i]);
        out[S + i] = Action::new(0.0, 0.0, steer[i]);
        out[2 * S + i] = Action::new(0.0, 1.0, steer[i]);
        i += 1;
    }
    out
}

impl ActionSet {
    /// Every set, in the order `--help` lists them.
    pub const ALL: [ActionSet; 5] = [ActionSet::Paper6, ActionSet::Paper12, ActionSet::Full15, ActionSet::Full21, ActionSet::Full27];

    /// The actions, in index order.
    #[must_use]
    pub fn actions(self) -> &'static [Action] {
        match self {
            ActionSet::Paper6 => &PAPER6,
            ActionSet::Paper12 => &PAPER12,
            ActionSet::Full15 => &FULL15,
            ActionSet::Full21 => &FULL21,
            ActionSet::Full27 => &FULL27,
        }
    }

    /// The configuration's spelling.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ActionSet::Paper6 => "paper6",
            ActionSet::Paper12 => "paper12",
            ActionSet::Full15 => "full15",
            ActionSet::Full21 => "full21",
            ActionSet::Full27 => "full27",
        }
    }

    /// The set named `name`; the error lists the valid names.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|s| s.name() == name).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|s| s.name()).collect();
            format!("unknown action set `{name}`: expected one of {}", names.join(", "))
        })
    }

    /// The index of the action nearest to `control`, measured in (throttle − brake, steer) with
    /// each axis divided by the set's own spacing on it (its range over its distinct values less
    /// one), so that one step of the set counts the same on both axes. Ties go to the lower index.
    #[must_use]
    pub fn nearest(self, control: Action) -> usize {
        let c = control.clamped();
        let actions = self.actions();
        let (du, ds) = self.spacings();
        let (u, s) = (c.throttle - c.brake, c.steer);
        let mut best = (f32::INFINITY, 0);
        for (i, a) in actions.iter().enumerate() {
            let d = ((a.throttle - a.brake - u) / du).powi(2) + ((a.steer - s) / ds).powi(2);
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }
}

impl ActionSet {
    /// The set's spacing on (throttle − brake, steer), worked out once per set: [`ActionSet::nearest`]
    /// runs every step of a quantised driver.
    fn spacings(self) -> (f32, f32) {
        static SPACINGS: OnceLock<Vec<(f32, f32)>> = OnceLock::new();
        let all = SPACINGS.get_or_init(|| {
            ActionSet::ALL
                .iter()
                .map(|set| {
                    let a = set.actions();
                    (spacing(a.iter().map(|a| a.throttle - a.brake)), spacing(a.iter().map(|a| a.steer)))
                })
                .collect()
        });
        all[ActionSet::ALL.iter().position(|&s| s == self).expect("every set is in ALL")]
    }
}

/// The mean gap between the distinct values of an axis (1 when it has one value).
fn spacing(values: impl Iterator<Item = f32>) -> f32 {
    let mut v: Vec<f32> = values.collect();
    v.sort_by(f32::total_cmp);
    v.dedup();
    match v.len() {
        0 | 1 => 1.0,
        n => (v[n - 1] - v[0]) / (n - 1) as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_have_their_documented_sizes_and_names_round_trip() {
        let sizes: Vec<usize> = ActionSet::ALL.iter().map(|s| s.actions().len()).collect();
        assert_eq!(sizes, [6, 12, 15, 21, 27]);
        for s in ActionSet::ALL {
            assert_eq!(ActionSet::from_name(s.name()), Ok(s));
        }
        assert_eq!(
            ActionSet::from_name("full").unwrap_err(),
            "unknown action set `full`: expected one of paper6, paper12, full15, full21, full27"
        );
    }

    #[test]
    fn the_full_set_brakes_at_the_limit_coasts_and_brakes_while_steering() {
        let a = ActionSet::Full15.actions();
        assert!(a.iter().any(|x| x.brake == 1.0 && x.steer != 0.0));
        assert!(a.iter().any(|x| x.brake == 0.0 && x.throttle == 0.0));
        // Each action is its own nearest.
        for s in ActionSet::ALL {
            for (i, &x) in s.actions().iter().enumerate() {
                assert_eq!(s.nearest(x), i, "{s:?} {x:?}");
            }
        }
    }

    #[test]
    fn nearest_measures_both_axes_in_the_sets_spacing() {
        let full = ActionSet::Full15;
        // Hard braking while steering a little right: full brake, steer 0.35.
        assert_eq!(full.actions()[full.nearest(Action::new(0.0, 0.8, 0.3))], Action::new(0.0, 1.0, 0.35));
        // A gentle throttle rounds to coasting, a firm one to full throttle.
        assert_eq!(full.actions()[full.nearest(Action::new(0.3, 0.0, 0.0))], Action::new(0.0, 0.0, 0.0));
        assert_eq!(full.actions()[full.nearest(Action::new(0.7, 0.0, 0.0))], Action::new(1.0, 0.0, 0.0));
        // paper6 has no coast and brakes at 0.1: any braking maps to it.
        let p6 = ActionSet::Paper6;
        assert_eq!(p6.actions()[p6.nearest(Action::new(0.0, 1.0, 0.0))], Action::new(0.0, 0.1, 0.0));
        // NaN controls are clamped to 0 first.
        assert_eq!(p6.nearest(Action::new(f32::NAN, 0.0, 0.0)), p6.nearest(Action::new(0.0, 0.0, 0.0)));
    }
}
