//! Discrete action sets: the DQN picks an index, the environment receives (throttle, brake, steer).

use serde::{Deserialize, Serialize};

use crate::vehicle::Action;

/// A named preset of discrete actions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionSet {
    /// The paper code's six: forward, forward-left, forward-right, brake, brake-left, brake-right.
    #[default]
    Paper6,
}

const PAPER6: [Action; 6] = [
    Action::new(1.0, 0.0, 0.0),
    Action::new(1.0, 0.0, -1.0),
    Action::new(1.0, 0.0, 1.0),
    Action::new(0.0, 0.1, 0.0),
    Action::new(0.0, 0.1, -0.1),
    Action::new(0.0, 0.1, 0.1),
];

impl ActionSet {
    /// The actions, in index order.
    #[must_use]
    pub fn actions(self) -> &'static [Action] {
        match self {
            ActionSet::Paper6 => &PAPER6,
        }
    }
}
