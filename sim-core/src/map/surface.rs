//! The ground surface as a raster: what lies at each point of the map (road, shoulder, sidewalk…).
//!
//! Built once from the road geometry; answers "is this point drivable?" in O(1) for collisions
//! and gives the camera its ground texture.

use crate::math::{Vec2, cross};

/// What the ground is at a point. Ordered: later kinds are painted over earlier ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum Surface {
    /// Grass, lots: not drivable.
    Offroad = 0,
    /// Raised pavement beyond the curb: not drivable.
    Sidewalk = 1,
    /// Parking strip beside the outermost lane: drivable.
    Shoulder = 2,
    /// A lane.
    Road = 3,
    /// A junction's area.
    Junction = 4,
    /// A white lane line (dividers and edges): drivable.
    WhiteLine = 5,
    /// The yellow centre line between the two directions: drivable.
    YellowLine = 6,
}

/// Flag bit of a raster cell: the cell lies in the shade of an overpass deck.
pub const SHADE: u8 = 0x80;

impl Surface {
    /// Whether a vehicle may be here.
    #[must_use]
    pub fn is_drivable(self) -> bool {
        self >= Surface::Shoulder
    }

    /// The surface of a raw raster cell (the shade flag ignored).
    #[must_use]
    pub fn from_u8(v: u8) -> Self {
        match v & !SHADE {
            1 => Surface::Sidewalk,
            2 => Surface::Shoulder,
            3 => Surface::Road,
            4 => Surface::Junction,
            5 => Surface::WhiteLine,
            6 => Surface::YellowLine,
            _ => Surface::Offroad,
        }
    }
}

/// A grid of [`Surface`] cells over the map's bounding box.
#[derive(Debug, Clone)]
pub struct SurfaceRaster {
    /// World position of the corner of cell (0, 0).
    pub origin: Vec2,
    /// Cell size, metres.
    pub cell: f32,
    pub width: usize,
    pub height: usize,
    cells: Vec<u8>,
    /// Coarser copies for distant ground (level k has cells 2^k times larger), built by
    /// [`SurfaceRaster::build_levels`]. Level 0 is this raster itself.
    levels: Vec<RasterLevel>,
}

/// One level of the raster pyramid: cells and what is needed to address them quickly.
#[derive(Debug, Clone)]
pub struct RasterLevel {
    pub origin: Vec2,
    /// Cells per metre.
    pub inv_cell: f32,
    pub width: usize,
    pub height: usize,
    pub cells: Vec<u8>,
}

impl RasterLevel {
    /// The raw cell at fractional cell coordinates (0 outside).
    #[inline]
    #[must_use]
    pub fn sample(&self, fx: f32, fy: f32) -> u8 {
        if fx >= 0.0 && fy >= 0.0 {
            let (ix, iy) = (fx as usize, fy as usize);
            if ix < self.width && iy < self.height {
                return self.cells[iy * self.width + ix];
            }
        }
        0
    }
}

impl SurfaceRaster {
    /// An all-offroad raster covering `[min, max]`.
    #[must_use]
    pub fn new(min: Vec2, max: Vec2, cell: f32) -> Self {
        let width = (((max.x - min.x) / cell).ceil() as usize).max(1);
        let height = (((max.y - min.y) / cell).ceil() as usize).max(1);
        Self { origin: min, cell, width, height, cells: vec![0; width * height], levels: Vec::new() }
    }

    /// Builds `n` levels of coarser copies (level 0 = this raster). Level 1 keeps the highest kind
    /// of each 2×2 block so that lane lines survive; higher levels keep each block's first cell.
    pub fn build_levels(&mut self, n: usize) {
        let mut levels = vec![RasterLevel {
            origin: self.origin,
            inv_cell: 1.0 / self.cell,
            width: self.width,
            height: self.height,
            cells: self.cells.clone(),
        }];
        for k in 1..n.max(1) {
            let prev = &levels[k - 1];
            let (w, h) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
            let at = |x: usize, y: usize| if x < prev.width && y < prev.height { prev.cells[y * prev.width + x] } else { 0 };
            let mut cells = Vec::with_capacity(w * h);
            for y in 0..h {
                for x in 0..w {
                    let v = if k == 1 {
                        let kids = [at(2 * x, 2 * y), at(2 * x + 1, 2 * y), at(2 * x, 2 * y + 1), at(2 * x + 1, 2 * y + 1)];
                        let shade = kids[0] & SHADE;
                        shade | kids.iter().map(|c| c & !SHADE).max().unwrap_or(0)
                    } else {
                        at(2 * x, 2 * y)
                    };
                    cells.push(v);
                }
            }
            levels.push(RasterLevel { origin: self.origin, inv_cell: prev.inv_cell / 2.0, width: w, height: h, cells });
        }
        self.levels = levels;
    }

    /// The levels built by [`Self::build_levels`] (empty before).
    #[must_use]
    pub fn levels(&self) -> &[RasterLevel] {
        &self.levels
    }

    /// The surface at a world point (offroad outside the raster).
    #[inline]
    #[must_use]
    pub fn at(&self, p: Vec2) -> Surface {
        let fx = (p.x - self.origin.x) / self.cell;
        let fy = (p.y - self.origin.y) / self.cell;
        if fx < 0.0 || fy < 0.0 {
            return Surface::Offroad;
        }
        let (ix, iy) = (fx as usize, fy as usize);
        if ix >= self.width || iy >= self.height {
            return Surface::Offroad;
        }
        Surface::from_u8(self.cells[iy * self.width + ix])
    }

    /// The raw cell at a world point (surface kind and flags; 0 outside the raster).
    #[inline]
    #[must_use]
    pub fn raw_at(&self, p: Vec2) -> u8 {
        let fx = (p.x - self.origin.x) / self.cell;
        let fy = (p.y - self.origin.y) / self.cell;
        if fx < 0.0 || fy < 0.0 {
            return 0;
        }
        let (ix, iy) = (fx as usize, fy as usize);
        if ix >= self.width || iy >= self.height {
            return 0;
        }
        self.cells[iy * self.width + ix]
    }

    /// Raw cells, row-major from `origin` (row = y).
    #[must_use]
    pub fn cells(&self) -> &[u8] {
        &self.cells
    }

    /// Paints `kind` into every cell whose centre is inside the convex polygon `poly` (either
    /// orientation), never lowering a cell already painted with a later kind.
    pub fn fill_convex(&mut self, poly: &[Vec2], kind: Surface) {
        self.for_cells_in_convex(poly, |cell| *cell = (*cell & SHADE) | (*cell & !SHADE).max(kind as u8));
    }

    /// Sets the [`SHADE`] flag on every cell whose centre is inside the convex polygon `poly`.
    pub fn shade_convex(&mut self, poly: &[Vec2]) {
        self.for_cells_in_convex(poly, |cell| *cell |= SHADE);
    }

    fn for_cells_in_convex(&mut self, poly: &[Vec2], mut apply: impl FnMut(&mut u8)) {
        if poly.len() < 3 {
            return;
        }
        let (mut lo, mut hi) = (poly[0], poly[0]);
        for p in poly {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let x0 = ((lo.x - self.origin.x) / self.cell).floor().max(0.0) as usize;
        let y0 = ((lo.y - self.origin.y) / self.cell).floor().max(0.0) as usize;
        let x1 = (((hi.x - self.origin.x) / self.cell).ceil().max(0.0) as usize).min(self.width);
        let y1 = (((hi.y - self.origin.y) / self.cell).ceil().max(0.0) as usize).min(self.height);
        let orientation = polygon_area2(poly).signum();
        for iy in y0..y1 {
            for ix in x0..x1 {
                let c = self.origin + Vec2::new((ix as f32 + 0.5) * self.cell, (iy as f32 + 0.5) * self.cell);
                let inside = (0..poly.len()).all(|i| {
                    let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                    cross(b - a, c - a) * orientation >= 0.0
                });
                if inside {
                    apply(&mut self.cells[iy * self.width + ix]);
                }
            }
        }
    }
}

fn polygon_area2(poly: &[Vec2]) -> f32 {
    (0..poly.len()).map(|i| cross(poly[i], poly[(i + 1) % poly.len()])).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_marks_inside_only_and_keeps_higher_kinds() {
        let mut r = SurfaceRaster::new(Vec2::ZERO, Vec2::new(10.0, 10.0), 0.5);
        let square = [Vec2::new(2.0, 2.0), Vec2::new(6.0, 2.0), Vec2::new(6.0, 6.0), Vec2::new(2.0, 6.0)];
        r.fill_convex(&square, Surface::Road);
        assert_eq!(r.at(Vec2::new(4.0, 4.0)), Surface::Road);
        assert_eq!(r.at(Vec2::new(1.0, 4.0)), Surface::Offroad);
        // Clockwise polygon, lower kind: does not overwrite.
        let cw: Vec<Vec2> = square.iter().rev().copied().collect();
        r.fill_convex(&cw, Surface::Sidewalk);
        assert_eq!(r.at(Vec2::new(4.0, 4.0)), Surface::Road);
        assert_eq!(r.at(Vec2::new(-1.0, 4.0)), Surface::Offroad);
        assert_eq!(r.at(Vec2::new(40.0, 4.0)), Surface::Offroad);
    }
}
