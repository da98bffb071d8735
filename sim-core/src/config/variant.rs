//! [`Variant`]: which agent an environment serves, the paper's method or its baseline. Both the
//! observation (`env.rs`) and the reward (`reward.rs`) depend on it.

use serde::{Deserialize, Serialize};

/// Which agent the environment serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// The paper's method: d in the observation, r_w in the reward.
    #[default]
    Hybrid,
    /// The paper's baseline: camera and speed only; no d, no r_w.
    EndToEnd,
}
