//! A hazard's still objects: cones, barriers, the parked car that hides a walker.

use serde::Serialize;

use crate::collision::{CollisionKind, Obb};

/// What a prop is (its collision kind and colour follow).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PropKind {
    Cone,
    Barrier,
    /// A car parked on the shoulder that hides a walker.
    ParkedCar,
}

impl PropKind {
    /// What hitting it counts as.
    #[must_use]
    pub fn collision(self) -> CollisionKind {
        match self {
            PropKind::Cone | PropKind::Barrier => CollisionKind::Construction,
            PropKind::ParkedCar => CollisionKind::ParkedCar,
        }
    }
}

/// A still object of a hazard.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prop {
    pub body: Obb,
    /// Height in the camera, metres.
    pub height: f32,
    pub kind: PropKind,
}
