//! The tally of one driven episode: return, steps, how it ended, and the sums behind mean d and
//! mean speed. `actor drive` and `actor eval` both keep one per run.

use sim_core::collision::CollisionKind;
use sim_core::env::StepResult;

/// What one driven episode came to.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Episode {
    /// Cumulative reward (the paper's metric).
    pub ret: f64,
    pub steps: u32,
    pub arrived: bool,
    pub collision: Option<CollisionKind>,
    /// Sums over steps of d (m) and speed (m/s), for the means.
    sum_d: f64,
    sum_speed: f64,
    pub done: bool,
}

impl Episode {
    /// Adds a step's result; returns whether the episode is over.
    pub fn record(&mut self, r: &StepResult) -> bool {
        self.ret += f64::from(r.reward);
        self.steps = r.info.steps;
        self.sum_d += f64::from(r.info.d);
        self.sum_speed += f64::from(r.info.speed);
        self.done = r.terminated || r.truncated;
        if self.done {
            self.arrived = r.info.arrived;
            self.collision = r.info.collision;
        }
        self.done
    }

    /// Mean distance to the closest waypoint over the episode's steps, metres.
    #[must_use]
    pub fn mean_d(&self) -> f64 {
        self.sum_d / f64::from(self.steps.max(1))
    }

    /// Mean speed over the episode's steps, m/s.
    #[must_use]
    pub fn mean_speed(&self) -> f64 {
        self.sum_speed / f64::from(self.steps.max(1))
    }
}
