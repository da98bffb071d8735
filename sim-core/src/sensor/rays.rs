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

/// Per raster cell, the chessboard distance in cells to the nearest cell off the drivable surface
/// (0 on such a cell, 1 next to one or to the raster's border, at most 255): every cell closer than
/// that is drivable, so a ray may jump that far less one cell without missing the road's edge.
/// Worked out once per town (`Town::edge_clearance`).
#[must_use]
pub fn clearance(surface: &SurfaceRaster) -> Vec<u8> {
    let (w, h) = (surface.width, surface.height);
    let mut d: Vec<u8> = surface.cells().iter().map(|&c| if Surface::from_u8(c).is_drivable() { 255 } else { 0 }).collect();
    let at = |d: &[u8], x: isize, y: isize| {
        if x < 0 || y < 0 || x >= w as isize || y >= h as isize { 0 } else { d[y as usize * w + x as usize] }
    };
    for pass in [false, true] {
        for k in 0..w * h {
            let k = if pass { w * h - 1 - k } else { k };
            if d[k] == 0 {
                continue;
            }
            let (x, y) = ((k % w) as isize, (k / w) as isize);
            let s = if pass { 1 } else { -1 };
            let m = [at(&d, x + s, y), at(&d, x + s, y + s), at(&d, x, y + s), at(&d, x - s, y + s)].into_iter().min().unwrap_or(0);
            d[k] = d[k].min(m.saturating_add(1));
        }
    }
    d
}

/// Raster cells per side of a block of [`EdgeClearance`].
pub const BLOCK: usize = 4;

/// Per block of `BLOCK`×`BLOCK` raster cells, the least [`clearance`] of its cells: small enough
/// to stay in cache while a ray jumps across the map by it.
#[derive(Debug, Clone)]
pub struct EdgeClearance {
    width: usize,
    height: usize,
    blocks: Vec<u8>,
}

impl EdgeClearance {
    #[must_use]
    pub fn new(surface: &SurfaceRaster) -> Self {
        let fine = clearance(surface);
        let (width, height) = (surface.width.div_ceil(BLOCK), surface.height.div_ceil(BLOCK));
        let mut blocks = vec![255u8; width * height];
        for (k, &c) in fine.iter().enumerate() {
            let b = &mut blocks[(k / surface.width / BLOCK) * width + (k % surface.width) / BLOCK];
            *b = (*b).min(c);
        }
        Self { width, height, blocks }
    }

    /// The least clearance of the block holding cell (`x`, `y`) (0 outside).
    #[inline]
    fn at(&self, x: usize, y: usize) -> u8 {
        let (bx, by) = (x / BLOCK, y / BLOCK);
        if bx < self.width && by < self.height { self.blocks[by * self.width + bx] } else { 0 }
    }
}

/// The distance from `o` along the unit `u` to the first cell off the drivable surface, at most
/// `max` (0 when `o` is off it): stepping a cell at a time near the edge, and elsewhere jumping
/// by the block's clearance (`edge` of `surface`), which never skips a cell off the road.
#[must_use]
pub fn edge_distance(surface: &SurfaceRaster, edge: &EdgeClearance, o: Vec2, u: Vec2, max: f32) -> f32 {
    let inv = 1.0 / surface.cell;
    let (ox, oy) = ((o.x - surface.origin.x) * inv, (o.y - surface.origin.y) * inv);
    let (w, h) = (surface.width, surface.height);
    let cells = surface.cells();
    let t_max = max * inv;
    let mut t = 0.0f32;
    loop {
        let (fx, fy) = (ox + u.x * t, oy + u.y * t);
        if !(fx >= 0.0 && fy >= 0.0 && (fx as usize) < w && (fy as usize) < h) {
            return (t * surface.cell).min(max);
        }
        let (x, y) = (fx as usize, fy as usize);
        let n = edge.at(x, y);
        if n >= 2 {
            t += f32::from(n - 1);
        } else if Surface::from_u8(cells[y * w + x]).is_drivable() {
            t += 1.0;
        } else {
            return (t * surface.cell).min(max);
        }
        if t > t_max {
            return max;
        }
    }
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
        let fine = clearance(&r);
        // The road's cells at its middle are 20 cells from its long sides.
        assert_eq!(fine[20 * r.width + 60], 20);
        assert_eq!(fine[20 * r.width + 130], 0);
        let c = EdgeClearance::new(&r);
        let o = Vec2::new(5.0, 5.0);
        let ahead = edge_distance(&r, &c, o, Vec2::X, 50.0);
        assert!((ahead - 25.0).abs() <= 0.25, "{ahead}");
        let left = edge_distance(&r, &c, o, Vec2::Y, 50.0);
        assert!((left - 5.0).abs() <= 0.25, "{left}");
        assert_eq!(edge_distance(&r, &c, o, Vec2::Y, 3.0), 3.0);
        assert_eq!(edge_distance(&r, &c, Vec2::new(35.0, 5.0), Vec2::X, 50.0), 0.0);
        // Slanted: the same first cell as a walk one cell at a time along the ray.
        for k in 0..32 {
            let a = k as f32 * 0.2;
            let u = Vec2::new(a.cos(), a.sin());
            let jumped = edge_distance(&r, &c, Vec2::new(7.3, 4.1), u, 50.0);
            let walked = (0..=400).map(|i| i as f32 * 0.125).find(|&t| !r.at(Vec2::new(7.3, 4.1) + u * t).is_drivable()).unwrap();
            assert!((jumped - walked).abs() <= 0.4, "angle {a}: {jumped} vs {walked}");
        }
    }
}
