//! Collision detection: oriented boxes (parry2d's SAT test) behind cheap broad phases — a uniform
//! grid over the static obstacles and sort-and-sweep over vehicles — and the drivable-area test.

use parry2d::math::Pose2;
use parry2d::query::details::intersection_test_cuboid_cuboid;
use parry2d::shape::Cuboid;
use serde::Serialize;

use crate::map::{Map, ObstacleKind, StaticObstacle};
use crate::math::{Vec2, cos, sin};

/// What the ego vehicle hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CollisionKind {
    /// A moving traffic vehicle.
    Vehicle,
    /// A parked car.
    ParkedCar,
    Building,
    Pole,
    /// An overpass pillar.
    Pillar,
    /// A wheel left the drivable surface (onto a curb, sidewalk or grass).
    OffRoad,
    /// A walker (a hazard's).
    Pedestrian,
    /// A cone or barrier of a construction closure.
    Construction,
}

impl CollisionKind {
    /// The kind for a static obstacle.
    #[must_use]
    pub fn of_obstacle(kind: ObstacleKind) -> Self {
        match kind {
            ObstacleKind::Building => Self::Building,
            ObstacleKind::Pole => Self::Pole,
            ObstacleKind::Pillar => Self::Pillar,
        }
    }

    /// A short lowercase name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Vehicle => "vehicle",
            Self::ParkedCar => "parked_car",
            Self::Building => "building",
            Self::Pole => "pole",
            Self::Pillar => "pillar",
            Self::OffRoad => "off_road",
            Self::Pedestrian => "pedestrian",
            Self::Construction => "construction",
        }
    }
}

/// An oriented box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obb {
    pub centre: Vec2,
    pub half: Vec2,
    /// Radians.
    pub angle: f32,
}

impl Obb {
    #[must_use]
    pub fn new(centre: Vec2, half: Vec2, angle: f32) -> Self {
        Self { centre, half, angle }
    }

    /// The four corners, counter-clockwise from the front right.
    #[must_use]
    pub fn corners(&self) -> [Vec2; 4] {
        let (c, s) = (cos(self.angle), sin(self.angle));
        let ax = Vec2::new(c, s) * self.half.x;
        let ay = Vec2::new(-s, c) * self.half.y;
        [self.centre + ax - ay, self.centre + ax + ay, self.centre - ax + ay, self.centre - ax - ay]
    }

    /// Axis-aligned bounds (min, max).
    #[must_use]
    pub fn aabb(&self) -> (Vec2, Vec2) {
        let (c, s) = (cos(self.angle).abs(), sin(self.angle).abs());
        let ext = Vec2::new(c * self.half.x + s * self.half.y, s * self.half.x + c * self.half.y);
        (self.centre - ext, self.centre + ext)
    }

    /// Exact overlap test (separating axes), after a bounding-circle rejection.
    #[must_use]
    pub fn intersects(&self, other: &Obb) -> bool {
        let r = self.half.length() + other.half.length();
        if self.centre.distance_squared(other.centre) > r * r {
            return false;
        }
        let p1 = Pose2::new(self.centre, self.angle);
        let p2 = Pose2::new(other.centre, other.angle);
        intersection_test_cuboid_cuboid(&p1.inv_mul(&p2), &Cuboid::new(self.half), &Cuboid::new(other.half))
    }
}

impl From<&StaticObstacle> for Obb {
    fn from(o: &StaticObstacle) -> Self {
        Obb::new(o.centre, o.half_extents, o.angle)
    }
}

/// A uniform grid over the map's static obstacles: each cell lists the obstacles whose bounds
/// touch it.
#[derive(Debug, Clone)]
pub struct StaticGrid {
    origin: Vec2,
    cell: f32,
    width: usize,
    height: usize,
    cells: Vec<Vec<u32>>,
    boxes: Vec<(Obb, CollisionKind)>,
}

impl StaticGrid {
    /// Cell size, metres.
    pub const CELL: f32 = 10.0;

    /// Indexes the obstacles of `map`.
    #[must_use]
    pub fn new(map: &Map) -> Self {
        let origin = map.surface.origin;
        let width = ((map.surface.width as f32 * map.surface.cell) / Self::CELL).ceil() as usize + 1;
        let height = ((map.surface.height as f32 * map.surface.cell) / Self::CELL).ceil() as usize + 1;
        let mut grid = Self { origin, cell: Self::CELL, width, height, cells: vec![Vec::new(); width * height], boxes: Vec::new() };
        for o in &map.obstacles {
            let obb = Obb::from(o);
            let id = grid.boxes.len() as u32;
            grid.boxes.push((obb, CollisionKind::of_obstacle(o.kind)));
            let (lo, hi) = obb.aabb();
            let ((x0, y0), (x1, y1)) = (grid.cell_of(lo), grid.cell_of(hi));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    grid.cells[y * width + x].push(id);
                }
            }
        }
        grid
    }

    fn cell_of(&self, p: Vec2) -> (usize, usize) {
        let f = (p - self.origin) / self.cell;
        (f.x.clamp(0.0, (self.width - 1) as f32) as usize, f.y.clamp(0.0, (self.height - 1) as f32) as usize)
    }

    /// Appends to `out` the obstacles whose bounds touch a cell over the rectangle `[lo, hi]`,
    /// each once, in ascending order of their index (`out` is cleared first).
    pub fn obstacles_in(&self, lo: Vec2, hi: Vec2, out: &mut Vec<u32>) {
        out.clear();
        let ((x0, y0), (x1, y1)) = (self.cell_of(lo), self.cell_of(hi));
        for y in y0..=y1 {
            out.extend(self.cells[y * self.width + x0..=y * self.width + x1].iter().flatten());
        }
        out.sort_unstable();
        out.dedup();
    }

    /// Obstacle `id`'s box and what hitting it counts as.
    #[must_use]
    pub fn obstacle(&self, id: u32) -> (Obb, CollisionKind) {
        self.boxes[id as usize]
    }

    /// The first static obstacle that `body` overlaps, if any.
    #[must_use]
    pub fn hit(&self, body: &Obb) -> Option<CollisionKind> {
        let (lo, hi) = body.aabb();
        let ((x0, y0), (x1, y1)) = (self.cell_of(lo), self.cell_of(hi));
        for y in y0..=y1 {
            for x in x0..=x1 {
                for &id in &self.cells[y * self.width + x] {
                    let (obb, kind) = &self.boxes[id as usize];
                    if body.intersects(obb) {
                        return Some(*kind);
                    }
                }
            }
        }
        None
    }
}

/// Whether any corner of `body` is off the drivable surface.
#[must_use]
pub fn leaves_drivable_area(map: &Map, body: &Obb) -> bool {
    body.corners().iter().any(|&c| !map.is_drivable(c))
}

/// All overlapping pairs among `boxes` (indices, `i < j`), by sort-and-sweep along x.
#[must_use]
pub fn overlapping_pairs(boxes: &[Obb]) -> Vec<(usize, usize)> {
    let mut spans: Vec<(f32, f32, usize)> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let (lo, hi) = b.aabb();
            (lo.x, hi.x, i)
        })
        .collect();
    spans.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
    let mut pairs = Vec::new();
    for (k, &(_, hi, i)) in spans.iter().enumerate() {
        for &(lo2, _, j) in &spans[k + 1..] {
            if lo2 > hi {
                break;
            }
            if boxes[i].intersects(&boxes[j]) {
                pairs.push((i.min(j), i.max(j)));
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_4;

    fn car(x: f32, y: f32, angle: f32) -> Obb {
        Obb::new(Vec2::new(x, y), Vec2::new(2.25, 0.95), angle)
    }

    #[test]
    fn box_overlap_cases() {
        // Bumper to bumper with a 10 cm gap: no contact; touching by 10 cm: contact.
        assert!(!car(0.0, 0.0, 0.0).intersects(&car(4.6, 0.0, 0.0)));
        assert!(car(0.0, 0.0, 0.0).intersects(&car(4.4, 0.0, 0.0)));
        // Side by side in adjacent 3.5 m lanes: no contact.
        assert!(!car(0.0, 0.0, 0.0).intersects(&car(0.0, 3.5, 0.0)));
        // Rotated 45°: the corner reaches 2.25·cos45 + 0.95·sin45 ≈ 2.26 m sideways.
        assert!(car(0.0, 0.0, FRAC_PI_4).intersects(&car(0.0, 3.0, 0.0)));
        assert!(!car(0.0, 0.0, FRAC_PI_4).intersects(&car(0.0, 3.3, 0.0)));
        // Bounding circles overlap but boxes do not (crossed at right angles, corner gap).
        assert!(!car(0.0, 0.0, 0.0).intersects(&car(3.3, 2.3, std::f32::consts::FRAC_PI_2)));
    }

    #[test]
    fn corners_and_aabb_agree() {
        let b = car(10.0, -3.0, 0.7);
        let (lo, hi) = b.aabb();
        for c in b.corners() {
            assert!(c.x >= lo.x - 1e-4 && c.x <= hi.x + 1e-4 && c.y >= lo.y - 1e-4 && c.y <= hi.y + 1e-4);
        }
        assert!((b.corners()[0] - b.corners()[2]).length() - 2.0 * b.half.length() < 1e-4);
    }

    #[test]
    fn sweep_matches_all_pairs() {
        let boxes: Vec<Obb> = (0..60).map(|i| car((i * 37 % 50) as f32 * 1.3, (i * 11 % 17) as f32 * 1.1, i as f32 * 0.37)).collect();
        let mut brute = Vec::new();
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                if boxes[i].intersects(&boxes[j]) {
                    brute.push((i, j));
                }
            }
        }
        assert!(!brute.is_empty());
        assert_eq!(overlapping_pairs(&boxes), brute);
    }

    #[test]
    fn static_grid_finds_buildings_and_poles() {
        let map = Map::default_town();
        let grid = StaticGrid::new(&map);
        // Building centred at (30, 30), 34 m wide; a pole at (25, -8).
        assert_eq!(grid.hit(&car(30.0, 30.0, 0.0)), Some(CollisionKind::Building));
        assert_eq!(grid.hit(&car(14.0, 30.0, 0.0)), Some(CollisionKind::Building));
        assert_eq!(grid.hit(&car(10.0, 30.0, 0.0)), None);
        assert_eq!(grid.hit(&car(25.0, -8.0, 0.0)), Some(CollisionKind::Pole));
        assert_eq!(grid.hit(&car(50.0, -1.75, 0.0)), None);
    }

    #[test]
    fn drivable_area_is_lanes_shoulders_and_junctions() {
        let map = Map::default_town();
        // In the eastbound lane of the bottom street, in the parking shoulder, in a junction.
        assert!(!leaves_drivable_area(&map, &car(50.0, -1.75, 0.0)));
        assert!(!leaves_drivable_area(&map, &car(50.0, -4.5, 0.0)));
        assert!(!leaves_drivable_area(&map, &car(100.0, 100.0, 0.6)));
        // Across the curb onto the sidewalk (edge at 6 m), and in a city block.
        assert!(leaves_drivable_area(&map, &car(50.0, -5.8, 0.0)));
        assert!(leaves_drivable_area(&map, &car(50.0, 50.0, 0.0)));
    }
}
