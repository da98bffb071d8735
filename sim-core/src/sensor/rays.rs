//! Range rays: `N` rays from the ego's centre, evenly spaced around it, the first straight ahead,
//! counter-clockwise. Each measures the distance to the nearest obstacle along it (objects' boxes
//! and static obstacles) and the distance to the road's edge (the first point off the drivable
//! surface), both as fractions of the range (1: nothing within range).

use crate::map::{Surface, SurfaceRaster};
use crate::math::{Vec2, cos, sin};

use super::geometry::Box2;

/// The rays' directions in the ego's frame, worked out once per ray count.
#[derive(Debug, Clone, Default)]
pub struct RayFan {
    /// Unit directions, ego frame (x ahead, y left).
    dirs: Vec<Vec2>,
}

impl RayFan {
    /// The directions of `n` rays, the first straight ahead, counter-clockwise.
    pub fn directions(&mut self, n: usize) -> &[Vec2] {
        if self.dirs.len() != n {
            self.dirs.clear();
            self.dirs.extend((0..n).map(|k| {
                let a = std::f32::consts::TAU * k as f32 / n as f32;
                Vec2::new(cos(a), sin(a))
            }));
        }
        &self.dirs
    }
}

/// The distance from `o` along the unit `u` to the nearest of `boxes`, at most `max`.
#[must_use]
pub fn obstacle_distance(o: Vec2, u: Vec2, max: f32, boxes: &[&[Box2]]) -> f32 {
    let mut best = max;
    for set in boxes {
        for b in *set {
            if let Some(t) = b.ray(o, u, best) {
                best = t;
            }
        }
    }
    best
}

/// The distance from `o` along the unit `u` to the first point off the drivable surface, sampled
/// every raster cell; `max` when the surface stays drivable that far (0 when `o` is off it).
#[must_use]
pub fn edge_distance(surface: &SurfaceRaster, o: Vec2, u: Vec2, max: f32) -> f32 {
    let cells = surface.cells();
    let step = surface.cell;
    let inv = 1.0 / surface.cell;
    let (mut fx, mut fy) = ((o.x - surface.origin.x) * inv, (o.y - surface.origin.y) * inv);
    let (dx, dy) = (u.x * step * inv, u.y * step * inv);
    let (w, h) = (surface.width, surface.height);
    let n = (max / step) as usize;
    for k in 0..=n {
        let drivable = fx >= 0.0 && fy >= 0.0 && {
            let (ix, iy) = (fx as usize, fy as usize);
            ix < w && iy < h && Surface::from_u8(cells[iy * w + ix]).is_drivable()
        };
        if !drivable {
            return (k as f32 * step).min(max);
        }
        fx += dx;
        fy += dy;
    }
    max
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::Obb;

    #[test]
    fn a_wall_straight_ahead_at_a_known_distance() {
        let wall = [Box2::new(&Obb::new(Vec2::new(20.5, 0.0), Vec2::new(0.5, 10.0), 0.0))];
        let mut fan = RayFan::default();
        let dirs = fan.directions(4).to_vec();
        assert!((dirs[1] - Vec2::Y).length() < 1e-6, "the second of four rays points left");
        let d: Vec<f32> = dirs.iter().map(|&u| obstacle_distance(Vec2::ZERO, u, 50.0, &[&wall])).collect();
        assert!((d[0] - 20.0).abs() < 1e-4, "{d:?}");
        assert_eq!(&d[1..], &[50.0, 50.0, 50.0]);
        // Out of range: the ray's full length.
        assert_eq!(obstacle_distance(Vec2::ZERO, Vec2::X, 15.0, &[&wall]), 15.0);
    }

    #[test]
    fn the_road_edge_along_a_ray() {
        let mut r = SurfaceRaster::new(Vec2::ZERO, Vec2::new(40.0, 10.0), 0.25);
        r.fill_convex(&[Vec2::new(0.0, 0.0), Vec2::new(30.0, 0.0), Vec2::new(30.0, 10.0), Vec2::new(0.0, 10.0)], Surface::Road);
        let o = Vec2::new(5.0, 5.0);
        let ahead = edge_distance(&r, o, Vec2::X, 50.0);
        assert!((ahead - 25.0).abs() <= 0.25, "{ahead}");
        let left = edge_distance(&r, o, Vec2::Y, 50.0);
        assert!((left - 5.0).abs() <= 0.25, "{left}");
        assert_eq!(edge_distance(&r, o, Vec2::Y, 3.0), 3.0);
        assert_eq!(edge_distance(&r, Vec2::new(35.0, 5.0), Vec2::X, 50.0), 0.0);
    }
}
