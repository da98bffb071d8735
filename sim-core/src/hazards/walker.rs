//! Pedestrians: a 0.6 × 0.6 m footprint, 1.8 m tall in the camera, that stand still until their
//! trigger fires (the ego `trigger_time` seconds from their crossing) and then walk straight
//! across the road at their speed, stopping once on the far side.

use crate::collision::Obb;
use crate::math::Vec2;

/// Half the side of a walker's footprint, metres.
pub const WALKER_HALF: f32 = 0.3;
/// A walker's height in the camera, metres.
pub const WALKER_HEIGHT: f32 = 1.8;

/// One pedestrian.
#[derive(Debug, Clone, PartialEq)]
pub struct Walker {
    pub pos: Vec2,
    /// Unit direction it crosses in.
    pub direction: Vec2,
    /// Walking speed once started, m/s.
    pub speed: f32,
    /// How far it walks before it stops, metres.
    pub distance_left: f32,
    /// Whether it is walking.
    pub walking: bool,
}

impl Walker {
    /// Its footprint, facing where it walks.
    #[must_use]
    pub fn body(&self) -> Obb {
        Obb::new(self.pos, Vec2::splat(WALKER_HALF), crate::math::heading_of(self.direction))
    }

    /// Its velocity now, m/s.
    #[must_use]
    pub fn velocity(&self) -> Vec2 {
        if self.walking { self.direction * self.speed } else { Vec2::ZERO }
    }

    /// Walks for `dt` seconds if started.
    pub fn step(&mut self, dt: f32) {
        if !self.walking {
            return;
        }
        let d = (self.speed * dt).min(self.distance_left);
        self.pos += self.direction * d;
        self.distance_left -= d;
        if self.distance_left <= 0.0 {
            self.walking = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_walker_walks_its_distance_and_stops() {
        let mut w = Walker { pos: Vec2::ZERO, direction: Vec2::Y, speed: 1.5, distance_left: 3.0, walking: false };
        w.step(0.1);
        assert_eq!(w.pos, Vec2::ZERO, "not started");
        w.walking = true;
        for _ in 0..30 {
            w.step(0.1);
        }
        assert!((w.pos.y - 3.0).abs() < 1e-5 && !w.walking, "{w:?}");
        assert_eq!(w.velocity(), Vec2::ZERO);
        assert_eq!(w.body().half, Vec2::splat(0.3));
    }
}
