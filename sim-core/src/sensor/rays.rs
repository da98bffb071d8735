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

/// The boxes that the obstacle rays from one origin may hit, each with its offset from the origin
/// and that offset's squared length worked out once for all the rays.
#[derive(Debug, Clone, Default)]
pub struct Targets {
    origin: Vec2,
    seen: Vec<(Box2, Vec2, f32)>,
}

impl Targets {
    /// Keeps of `boxes` those a ray from `o` of length `max` may reach: a box farther than that by
    /// more than any rounding is hit by none (its entry would lie beyond `max`).
    pub fn gather(&mut self, o: Vec2, max: f32, boxes: &[&[Box2]]) {
        self.origin = o;
        self.seen.clear();
        for b in boxes.iter().flat_map(|set| set.iter()) {
            let oc = b.centre - o;
            let oc2 = oc.length_squared();
            let reach = (max + b.radius) * (1.0 + 1e-4) + 1e-3;
            if oc2 <= reach * reach {
                self.seen.push((*b, oc, oc2));
            }
        }
    }

    /// The distance along the unit `u` to the nearest box, at most `max`.
    #[must_use]
    pub fn distance(&self, u: Vec2, max: f32) -> f32 {
        let mut best = max;
        for (b, oc, oc2) in &self.seen {
            if let Some(t) = b.ray_from(self.origin, u, best, *oc, *oc2) {
                best = t;
            }
        }
        best
    }
}

/// Per raster cell, the chessboard distance in cells to the nearest cell off the drivable surface
/// (0 on such a cell, 1 next to one or to the raster's border, at most 255): every cell closer than
/// that is drivable, so a ray may jump that far less one cell without missing the road's edge.
/// Worked out once per town (`Town::edge_clearance`).
#[must_use]
pub fn clearance(surface: &SurfaceRaster) -> Vec<u8> {
    let (w, h) = (surface.width, surface.height);
    let mut d: Vec<u8> = surface.cells().iter().map(|&c| if Surface::from_u8(c).is_drivable() { 255 } else { 0 }).collect();
    // Forward from the left and the row above, then backward from the right and the row below;
    // cells beyond the raster count as off the road, so the border's cells are next to it.
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            if d[k] != 0 {
                let m = if x == 0 || y == 0 || x + 1 == w { 0 } else { d[k - 1].min(d[k - w - 1]).min(d[k - w]).min(d[k - w + 1]) };
                d[k] = d[k].min(m.saturating_add(1));
            }
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let k = y * w + x;
            if d[k] != 0 {
                let m = if x == 0 || y + 1 == h || x + 1 == w { 0 } else { d[k + 1].min(d[k + w + 1]).min(d[k + w]).min(d[k + w - 1]) };
                d[k] = d[k].min(m.saturating_add(1));
            }
        }
    }
    d
}

/// Raster cells per side of a block of [`EdgeClearance`].
pub const BLOCK: usize = 4;

/// Per block of `BLOCK`×`BLOCK` raster cells, the least [`clearance`] `m` of its cells: every
/// cell within `m - 1` of the block is drivable. Small enough to stay in cache while a ray hops
/// across the map by it.
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
        for (y, row) in fine.chunks_exact(surface.width).enumerate() {
            for (b, cells) in blocks[y / BLOCK * width..][..width].iter_mut().zip(row.chunks(BLOCK)) {
                *b = cells.iter().fold(*b, |m, &c| m.min(c));
            }
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

/// How far past a box's side a ray is sampled to find the cell beyond it, cells: more than the
/// rounding of a position on the largest raster, far less than a cell.
const NUDGE: f32 = 1.0 / 64.0;

/// The distance from `o` along the unit `u` to where it enters the first cell off the drivable
/// surface (or leaves the raster), at most `max` (0 when `o` is off it). The ray crosses in one
/// hop each box of cells known to be drivable: a block of `edge` with clearance `m` ≥ 1 and the
/// `m - 1` cells around it, or next to the edge the one cell it is in; so it passes over no cell
/// off the road, and the reading does not depend on where the hops land.
#[must_use]
pub fn edge_distance(surface: &SurfaceRaster, edge: &EdgeClearance, o: Vec2, u: Vec2, max: f32) -> f32 {
    let inv = 1.0 / surface.cell;
    let (ox, oy) = ((o.x - surface.origin.x) * inv, (o.y - surface.origin.y) * inv);
    let (w, h) = (surface.width, surface.height);
    let cells = surface.cells();
    let t_max = max * inv;
    // Parameter per cell of travel along each axis (infinite along an axis the ray does not move on).
    let (kx, ky) = (1.0 / u.x.abs(), 1.0 / u.y.abs());
    // `t`: where the ray entered the box it is in; `probe`: where it is sampled, just past `t`.
    let (mut t, mut probe) = (0.0f32, 0.0f32);
    loop {
        let (fx, fy) = (ox + u.x * probe, oy + u.y * probe);
        if !(fx >= 0.0 && fy >= 0.0 && (fx as usize) < w && (fy as usize) < h) {
            return (t * surface.cell).min(max);
        }
        let (x, y) = (fx as usize, fy as usize);
        let m = usize::from(edge.at(x, y));
        let (lo, hi) = if m >= 1 {
            let (bx, by) = (x / BLOCK * BLOCK, y / BLOCK * BLOCK);
            let r = m - 1;
            ((bx as f32 - r as f32, by as f32 - r as f32), ((bx + BLOCK + r).min(w) as f32, (by + BLOCK + r).min(h) as f32))
        } else if Surface::from_u8(cells[y * w + x]).is_drivable() {
            ((x as f32, y as f32), ((x + 1) as f32, (y + 1) as f32))
        } else {
            return (t * surface.cell).min(max);
        };
        // The box's side the ray leaves by (a NaN for an axis it does not move on loses the min).
        let dx = if u.x > 0.0 { hi.0 - fx } else { fx - lo.0 } * kx;
        let dy = if u.y > 0.0 { hi.1 - fy } else { fy - lo.1 } * ky;
        t = probe + dx.min(dy);
        if t > t_max {
            return max;
        }
        probe = t + NUDGE;
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
        let mut targets = Targets::default();
        targets.gather(Vec2::ZERO, 50.0, &[&wall]);
        let d: Vec<f32> = dirs.iter().map(|&u| targets.distance(u, 50.0)).collect();
        assert!((d[0] - 20.0).abs() < 1e-4, "{d:?}");
        assert_eq!(&d[1..], &[50.0, 50.0, 50.0]);
        // Out of range: the ray's full length; out of every ray's reach, not even a target.
        targets.gather(Vec2::ZERO, 15.0, &[&wall]);
        assert_eq!(targets.distance(Vec2::X, 15.0), 15.0);
        targets.gather(Vec2::new(-20.0, 0.0), 15.0, &[&wall]);
        assert!(targets.seen.is_empty());
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
        // Where the ray enters the first cell off the road (here the road's end) or leaves the
        // raster (its side), exactly but for rounding.
        let ahead = edge_distance(&r, &c, o, Vec2::X, 50.0);
        assert!((ahead - 25.0).abs() <= 1e-3, "{ahead}");
        let left = edge_distance(&r, &c, o, Vec2::Y, 50.0);
        assert!((left - 5.0).abs() <= 1e-3, "{left}");
        assert_eq!(edge_distance(&r, &c, o, Vec2::Y, 3.0), 3.0);
        assert_eq!(edge_distance(&r, &c, Vec2::new(35.0, 5.0), Vec2::X, 50.0), 0.0);
        // Slanted: the same first cell as a walk one cell at a time along the ray.
        for k in 0..32 {
            let a = k as f32 * 0.2;
            let u = Vec2::new(a.cos(), a.sin());
            let jumped = edge_distance(&r, &c, Vec2::new(7.3, 4.1), u, 50.0);
            let walked = (0..=400).map(|i| i as f32 * 0.125).find(|&t| !r.at(Vec2::new(7.3, 4.1) + u * t).is_drivable()).unwrap();
            assert!(jumped <= walked + 1e-3 && walked - jumped <= 0.125 + 1e-3, "angle {a}: {jumped} vs {walked}");
        }
    }

    /// Roads at odd angles across each other over a 40 m square: their edges cut cells anywhere.
    fn crossing_roads() -> SurfaceRaster {
        let mut r = SurfaceRaster::new(Vec2::ZERO, Vec2::new(40.0, 40.0), 0.25);
        let quads = [
            [(2.0, 15.0), (38.0, 17.0), (38.0, 23.0), (2.0, 21.0)],
            [(17.0, 2.0), (23.0, 2.0), (21.0, 38.0), (15.0, 38.0)],
            [(5.0, 7.0), (8.0, 4.0), (35.0, 31.0), (32.0, 34.0)],
        ];
        for q in quads {
            r.fill_convex(&q.map(|(x, y)| Vec2::new(x, y)), Surface::Road);
        }
        r
    }

    #[test]
    fn clearance_is_the_chessboard_distance_to_the_nearest_cell_off_the_road() {
        // Checked against its definition, cell by cell: the nearest off-road cell or the border.
        let r = crossing_roads();
        let fine = clearance(&r);
        let (w, h) = (r.width as isize, r.height as isize);
        let off =
            |x: isize, y: isize| x < 0 || y < 0 || x >= w || y >= h || !Surface::from_u8(r.cells()[(y * w + x) as usize]).is_drivable();
        for (k, &c) in fine.iter().enumerate().step_by(7) {
            let (x, y) = (k as isize % w, k as isize / w);
            let want = (0..=255)
                .find(|&n| (-n..=n).any(|i| off(x + i, y - n) || off(x + i, y + n) || off(x - n, y + i) || off(x + n, y + i)))
                .unwrap_or(255);
            assert_eq!(isize::from(c), want, "cell ({x}, {y})");
        }
    }

    #[test]
    fn the_road_edge_is_where_a_ray_first_enters_a_cell_off_the_road() {
        let r = crossing_roads();
        let c = EdgeClearance::new(&r);
        let off = |p: Vec2| !r.at(p).is_drivable();
        let step = r.cell / 32.0;
        for o in [Vec2::new(10.0, 18.3), Vec2::new(19.1, 19.7), Vec2::new(20.2, 33.0), Vec2::new(12.4, 11.1)] {
            for k in 0..90 {
                let a = k as f32 * 0.07;
                let u = Vec2::new(a.cos(), a.sin());
                let got = edge_distance(&r, &c, o, u, 30.0);
                // A walk in steps of a thirty-second of a cell finds nothing off the road before
                // the reading, and the first thing it finds is within a step of it (unless the
                // walk stepped over a corner the ray clips: then just past the reading is off).
                let walked = (0..).map(|i| i as f32 * step).take_while(|&t| t <= 30.0).find(|&t| off(o + u * t)).unwrap_or(30.0);
                let clipped = got < 30.0 && off(o + u * (got + r.cell / 64.0));
                assert!(got <= walked + 1e-3 && (walked - got <= step + 1e-3 || clipped), "{o:?} angle {a}: {got} vs {walked}");
            }
        }
    }
}
