//! The static obstacles (buildings, poles, overpass pillars: what the collision test counts at
//! ground level, `Town::statics`) near the ego, gathered from the town's grid into a cache that
//! serves every reading while the ego stays within [`MARGIN`] of where it was gathered.
//!
//! The cache holds every obstacle whose grid cells touch a square of half side
//! `reach + MARGIN` around the point it was gathered at: a superset of those within `reach` of
//! the ego while the ego is within `MARGIN` of that point. Which superset it holds changes no
//! reading (a line of sight is blocked or not, a ray's nearest hit is a minimum), so readings do
//! not depend on when the cache was refreshed.

use crate::collision::StaticGrid;
use crate::math::Vec2;

use super::geometry::Box2;

/// How far the ego may move before the cache is gathered again, metres.
pub const MARGIN: f32 = 10.0;

/// Static obstacles near the ego.
#[derive(Debug, Clone, Default)]
pub struct StaticCache {
    /// Where the boxes were gathered and for what reach; `None` before the first gathering.
    at: Option<(Vec2, f32)>,
    ids: Vec<u32>,
    boxes: Vec<Box2>,
    /// The cached boxes that reach within `reach` of the ego, this reading.
    pub near: Vec<Box2>,
}

impl StaticCache {
    /// Gathers into `near` the obstacles whose bounding circles reach within `reach` of
    /// `centre`, from the cache (refreshed first if `centre` has left it).
    pub fn update(&mut self, grid: &StaticGrid, centre: Vec2, reach: f32) {
        let fresh = self.at.is_some_and(|(at, r)| r == reach && at.distance_squared(centre) <= MARGIN * MARGIN);
        if !fresh {
            let half = Vec2::splat(reach + MARGIN);
            grid.obstacles_in(centre - half, centre + half, &mut self.ids);
            self.boxes.clear();
            self.boxes.extend(self.ids.iter().map(|&id| Box2::new(&grid.obstacle(id).0)));
            self.at = Some((centre, reach));
        }
        self.near.clear();
        self.near.extend(self.boxes.iter().filter(|b| {
            let r = reach + b.radius;
            b.centre.distance_squared(centre) <= r * r
        }));
    }

    /// Forgets the gathered boxes (another town).
    pub fn clear(&mut self) {
        self.at = None;
        self.boxes.clear();
        self.near.clear();
    }
}
