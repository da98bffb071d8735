//! The sensor's geometry: boxes with their axes worked out once per reading, and the tests every
//! line of sight and every ray asks of them (a bounding-circle rejection, then the exact slab test).

use crate::collision::Obb;
use crate::math::{Vec2, cos, cross, sin};

/// An oriented box as the sensor tests it: its unit axis along its length, half extents, and the
/// radius of its bounding circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Box2 {
    pub centre: Vec2,
    /// Unit vector along the box's length (its heading).
    pub axis: Vec2,
    pub half: Vec2,
    /// Radius of the bounding circle, metres.
    pub radius: f32,
}

impl Box2 {
    #[must_use]
    pub fn new(obb: &Obb) -> Self {
        Self::with_axis(obb.centre, Vec2::new(cos(obb.angle), sin(obb.angle)), obb.half)
    }

    #[must_use]
    pub fn with_axis(centre: Vec2, axis: Vec2, half: Vec2) -> Self {
        Self { centre, axis, half, radius: half.length() }
    }

    /// `p` in the box's frame (x along its axis, y to its left).
    #[inline]
    #[must_use]
    pub fn local(&self, p: Vec2) -> Vec2 {
        let d = p - self.centre;
        Vec2::new(d.dot(self.axis), cross(self.axis, d))
    }

    /// The four corners, counter-clockwise from the front right.
    #[must_use]
    pub fn corners(&self) -> [Vec2; 4] {
        let ax = self.axis * self.half.x;
        let ay = Vec2::new(-self.axis.y, self.axis.x) * self.half.y;
        [self.centre + ax - ay, self.centre + ax + ay, self.centre - ax + ay, self.centre - ax - ay]
    }

    /// The first parameter `t` in `[0, t_max]` at which `o + t·d` is inside the box (0 when `o`
    /// is), or `None` if that stretch misses it. `d` need not be a unit vector.
    #[inline]
    #[must_use]
    pub fn entry(&self, o: Vec2, d: Vec2, t_max: f32) -> Option<f32> {
        let lo = self.local(o);
        let ld = Vec2::new(d.dot(self.axis), cross(self.axis, d));
        let (mut t0, mut t1) = (0.0f32, t_max);
        for (p, v, h) in [(lo.x, ld.x, self.half.x), (lo.y, ld.y, self.half.y)] {
            if v.abs() < 1e-12 {
                if p.abs() > h {
                    return None;
                }
            } else {
                let inv = 1.0 / v;
                let (a, b) = ((-h - p) * inv, (h - p) * inv);
                let (a, b) = if a < b { (a, b) } else { (b, a) };
                t0 = t0.max(a);
                t1 = t1.min(b);
                if t0 > t1 {
                    return None;
                }
            }
        }
        Some(t0)
    }

    /// Whether the segment `a`–`b` touches the box.
    #[inline]
    #[must_use]
    pub fn blocks(&self, a: Vec2, b: Vec2) -> bool {
        self.blocks_sight(&Sight::new(a, b))
    }

    /// Whether the line of sight touches the box.
    #[inline]
    #[must_use]
    pub fn blocks_sight(&self, s: &Sight) -> bool {
        // Bounding circle against the segment first: most boxes are nowhere near it.
        let ac = self.centre - s.a;
        let t = (ac.dot(s.d) * s.inv_len2).clamp(0.0, 1.0);
        if (ac - s.d * t).length_squared() > self.radius * self.radius {
            return false;
        }
        self.entry(s.a, s.d, 1.0).is_some()
    }

    /// Distance along the ray from `o` in the unit direction `u` to the box, if it is hit within
    /// `max` (0 when `o` is inside).
    #[inline]
    #[must_use]
    pub fn ray(&self, o: Vec2, u: Vec2, max: f32) -> Option<f32> {
        let oc = self.centre - o;
        self.ray_from(o, u, max, oc, oc.length_squared())
    }

    /// [`Box2::ray`] given the offset `oc` of the box's centre from `o` and its squared length
    /// `oc2` (shared by every ray from `o`).
    #[inline]
    #[must_use]
    pub fn ray_from(&self, o: Vec2, u: Vec2, max: f32, oc: Vec2, oc2: f32) -> Option<f32> {
        let tc = oc.dot(u);
        let r = self.radius;
        if tc < -r || tc - r > max || oc2 - tc * tc > r * r {
            return None;
        }
        self.entry(o, u, max)
    }
}

/// A segment from `a` to `a + d`, with what every box's test of it shares worked out once.
#[derive(Debug, Clone, Copy)]
pub struct Sight {
    pub a: Vec2,
    pub d: Vec2,
    /// 1 / |d|² (0 for a point).
    pub inv_len2: f32,
}

impl Sight {
    #[must_use]
    pub fn new(a: Vec2, b: Vec2) -> Self {
        let d = b - a;
        let len2 = d.length_squared();
        Self { a, d, inv_len2: if len2 > 0.0 { 1.0 / len2 } else { 0.0 } }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_and_segments_against_a_turned_box() {
        let b = Box2::new(&Obb::new(Vec2::new(10.0, 0.0), Vec2::new(2.0, 1.0), std::f32::consts::FRAC_PI_2));
        // Turned a quarter: 2 m wide along x, so its near face is at x = 9.
        let t = b.ray(Vec2::ZERO, Vec2::X, 50.0).unwrap();
        assert!((t - 9.0).abs() < 1e-4, "{t}");
        assert_eq!(b.ray(Vec2::ZERO, Vec2::X, 8.0), None);
        assert_eq!(b.ray(Vec2::ZERO, -Vec2::X, 50.0), None);
        assert_eq!(b.ray(Vec2::new(0.0, 2.5), Vec2::X, 50.0), None);
        assert!(b.ray(Vec2::new(0.0, 1.9), Vec2::X, 50.0).is_some());
        assert_eq!(b.ray(Vec2::new(10.0, 0.0), Vec2::X, 50.0), Some(0.0));
        assert!(b.blocks(Vec2::ZERO, Vec2::new(20.0, 0.0)));
        assert!(!b.blocks(Vec2::ZERO, Vec2::new(8.9, 0.0)));
        assert!(!b.blocks(Vec2::new(0.0, 3.0), Vec2::new(20.0, 3.0)));
        let c = b.corners();
        assert!((c[0] - Vec2::new(11.0, 2.0)).length() < 1e-5, "{c:?}");
    }
}
