//! Which planner an environment uses (`[env] planner`).

use serde::{Deserialize, Serialize};

/// Which planner gives the waypoints.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PlannerKind {
    /// The A* route as planned at reset (today's).
    #[default]
    #[serde(rename = "astar")]
    Astar,
    /// The A* route bent around perceived hazards and obstacles.
    #[serde(rename = "astar+avoid")]
    AstarAvoid,
}

impl PlannerKind {
    /// The name in configuration and reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            PlannerKind::Astar => "astar",
            PlannerKind::AstarAvoid => "astar+avoid",
        }
    }
}
