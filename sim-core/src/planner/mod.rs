//! The planners that give the waypoints: `astar`, today's global route, and `astar+avoid`, the
//! same route bent around the hazards and static obstacles it perceives (ground truth, as a
//! perception module would report them). `[env] planner` picks one; it drives both the hybrid
//! agent's d and path features and the model-based driver.
//!
//! A planner's output is a lateral offset from the A* route along its arc length (the bent
//! waypoints are the route's, shifted by it) and, when no way round is clear, a point to stop at.

pub mod avoid;
pub mod kind;

use crate::collision::Obb;
use crate::hazards::Hazard;
use crate::route::Route;
use crate::town::Town;
use crate::traffic::Traffic;
use crate::vehicle::{VehicleParams, VehicleState};
pub use avoid::AvoidPlanner;
pub use kind::PlannerKind;

/// What a planner sees of the world each step.
#[derive(Debug, Clone, Copy)]
pub struct WorldView<'a> {
    pub town: &'a Town,
    pub route: &'a Route,
    pub ego: &'a VehicleState,
    /// The ego's arc length along the route.
    pub ego_s: f32,
    pub vehicle: &'a VehicleParams,
    pub traffic: &'a Traffic,
    /// Cars parked on shoulders.
    pub parked: &'a [Obb],
    pub hazard: Option<&'a Hazard>,
    /// The junction connector the ego holds the right to cross, if any.
    pub ego_hold: Option<crate::map::LaneId>,
}

/// A lateral offset from the route: 0 before `start`, rising linearly to `offset` at `full_from`,
/// held to `full_to`, back to 0 at `end` (arc lengths along the route).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detour {
    pub start: f32,
    pub full_from: f32,
    pub full_to: f32,
    pub end: f32,
    /// Metres, positive to the left.
    pub offset: f32,
}

impl Detour {
    /// The offset at arc length `s`.
    #[must_use]
    pub fn offset_at(&self, s: f32) -> f32 {
        if s <= self.start || s >= self.end {
            0.0
        } else if s < self.full_from {
            self.offset * (s - self.start) / (self.full_from - self.start)
        } else if s <= self.full_to {
            self.offset
        } else {
            self.offset * (self.end - s) / (self.end - self.full_to)
        }
    }
}

/// A planner of waypoints along the global route.
pub trait Planner {
    /// Replans for the world as it is now.
    fn update(&mut self, world: &WorldView<'_>);
    /// The detour from the route it asks for, if any.
    fn detour(&self) -> Option<Detour>;
    /// The route arc length to stop at when no way round is clear.
    fn stop_at(&self) -> Option<f32>;
}

/// The A* route as it is: no detour, no stop.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AstarPlanner;

impl Planner for AstarPlanner {
    fn update(&mut self, _world: &WorldView<'_>) {}
    fn detour(&self) -> Option<Detour> {
        None
    }
    fn stop_at(&self) -> Option<f32> {
        None
    }
}

/// The configured planner (a plain enum, so that an environment stays `Clone`).
#[derive(Debug, Clone, PartialEq)]
pub enum LocalPlanner {
    Astar(AstarPlanner),
    Avoid(AvoidPlanner),
}

impl LocalPlanner {
    #[must_use]
    pub fn new(kind: PlannerKind) -> Self {
        match kind {
            PlannerKind::Astar => Self::Astar(AstarPlanner),
            PlannerKind::AstarAvoid => Self::Avoid(AvoidPlanner::default()),
        }
    }
}

impl Planner for LocalPlanner {
    fn update(&mut self, world: &WorldView<'_>) {
        match self {
            Self::Astar(p) => p.update(world),
            Self::Avoid(p) => p.update(world),
        }
    }
    // Matched rather than dispatched through `&dyn Planner`: the step asks for the detour several
    // times, and for `astar` the answer (`None`) then inlines to nothing.
    #[inline]
    fn detour(&self) -> Option<Detour> {
        match self {
            Self::Astar(p) => p.detour(),
            Self::Avoid(p) => p.detour(),
        }
    }
    #[inline]
    fn stop_at(&self) -> Option<f32> {
        match self {
            Self::Astar(p) => p.stop_at(),
            Self::Avoid(p) => p.stop_at(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_detour_ramps_holds_and_returns() {
        let d = Detour { start: 10.0, full_from: 20.0, full_to: 30.0, end: 40.0, offset: 3.0 };
        assert_eq!(d.offset_at(5.0), 0.0);
        assert_eq!(d.offset_at(15.0), 1.5);
        assert_eq!(d.offset_at(25.0), 3.0);
        assert_eq!(d.offset_at(35.0), 1.5);
        assert_eq!(d.offset_at(45.0), 0.0);
    }

    #[test]
    fn kinds_have_the_issue_names() {
        assert_eq!(PlannerKind::AstarAvoid.name(), "astar+avoid");
        assert_eq!(PlannerKind::default(), PlannerKind::Astar);
    }
}
