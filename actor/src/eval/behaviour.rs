//! How a run drove around its hazard, not only how it scored: how far it left the route near the
//! hazard and whether it came back (a stalled car, a closed lane), and how fast it reached the
//! hazard point (a walker crossing there). Measured from the simulator's ground truth each step.

use serde::Serialize;
use sim_core::env::Env;

/// Route distance either side of the hazard point over which the lateral offset counts, metres:
/// room for a detour that starts well before a stalled car and ends after it.
pub const HAZARD_WINDOW_M: f32 = 40.0;
/// Past the hazard point by this much, the run has passed it, metres.
pub const PASSED_M: f32 = 10.0;
/// Back on the route: within this lateral offset of its centre line, metres (half a lane width
/// less half a car: in its own lane).
pub const BACK_ON_ROUTE_M: f32 = 0.75;
/// The ego's centre is this far behind its front bumper, metres: the front reaches the hazard
/// point when the centre is this far before it.
const HALF_LENGTH_M: f32 = 2.25;

/// A run's behaviour around its hazard (for a run without one: the offset over the whole route).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Behaviour {
    /// The largest |lateral offset| from the route's centre line, metres, within
    /// [`HAZARD_WINDOW_M`] of the hazard point along the route (the whole run without a hazard).
    pub max_abs_lateral_m: f64,
    /// Whether the ego got [`PASSED_M`] past the hazard point (`null` without a hazard).
    pub passed_hazard: Option<bool>,
    /// Whether, once past it, the ego was back within [`BACK_ON_ROUTE_M`] of the route's centre
    /// line (`null` without a hazard).
    pub back_on_route: Option<bool>,
    /// The ego's speed when its front first reached the hazard point, m/s (`null` without a
    /// hazard, or when it never got there).
    pub speed_at_hazard_ms: Option<f64>,
}

/// Follows one run step by step.
#[derive(Debug, Clone, Default)]
pub struct BehaviourWatch {
    b: Behaviour,
}

impl BehaviourWatch {
    /// Records the state after a step (and after the reset, before the first one).
    pub fn record(&mut self, env: &Env) {
        let (s, lateral) = (env.tracking.s, env.tracking.lateral.abs());
        let Some(hazard_s) = env.hazard.as_ref().map(|h| h.s) else {
            self.b.max_abs_lateral_m = self.b.max_abs_lateral_m.max(f64::from(lateral));
            return;
        };
        if (s - hazard_s).abs() <= HAZARD_WINDOW_M {
            self.b.max_abs_lateral_m = self.b.max_abs_lateral_m.max(f64::from(lateral));
        }
        if self.b.speed_at_hazard_ms.is_none() && s + HALF_LENGTH_M >= hazard_s {
            self.b.speed_at_hazard_ms = Some(f64::from(env.ego.speed));
        }
        let passed = s >= hazard_s + PASSED_M;
        self.b.passed_hazard = Some(self.b.passed_hazard == Some(true) || passed);
        self.b.back_on_route = Some(self.b.back_on_route == Some(true) || (passed && lateral <= BACK_ON_ROUTE_M));
    }

    /// What the run showed.
    #[must_use]
    pub fn finish(self) -> Behaviour {
        self.b
    }
}
