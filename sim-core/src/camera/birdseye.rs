//! The bird's-eye debug view: the map around the ego vehicle seen from above, north up, with the
//! vehicles, the ego (red), the A* route (green), its waypoints (blue) and the waypoint closest to
//! the ego (magenta); and, over it, what the vector sensor reads ([`BirdsEye::draw_vector`]).

use serde::{Deserialize, Serialize};

use super::image::Image;
use super::palette::{self, raster_table};
use super::scene::SceneBox;
use crate::collision::Obb;
use crate::config::error::ConfigError;
use crate::config::variant::Variant;
use crate::math::{Vec2, cross, dir};
use crate::route::Route;
use crate::sensor::geometry::Box2;
use crate::sensor::{RAY_FIELDS, VectorConfig};
use crate::town::Town;

/// Size and scale of the bird's-eye view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BirdsEyeConfig {
    /// Image side, pixels (default 256).
    pub size: u32,
    /// Metres per pixel (default 0.3: 77 m across).
    pub metres_per_pixel: f32,
}

impl Default for BirdsEyeConfig {
    fn default() -> Self {
        Self { size: 256, metres_per_pixel: 0.3 }
    }
}

impl BirdsEyeConfig {
    /// Checks every field; the error names it (prefixed `birdseye.`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(16..=4096).contains(&self.size) {
            return Err(ConfigError { field: "birdseye.size".into(), message: format!("{} pixels is outside 16..=4096", self.size) });
        }
        if !(self.metres_per_pixel.is_finite() && self.metres_per_pixel > 0.01 && self.metres_per_pixel < 100.0) {
            return Err(ConfigError {
                field: "birdseye.metres_per_pixel".into(),
                message: format!("{} must be between 0.01 and 100", self.metres_per_pixel),
            });
        }
        Ok(())
    }
}

/// The bird's-eye renderer.
#[derive(Debug, Clone)]
pub struct BirdsEye {
    cfg: BirdsEyeConfig,
    table: Box<[[u8; 3]; 256]>,
}

impl BirdsEye {
    pub fn new(cfg: &BirdsEyeConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self { cfg: cfg.clone(), table: Box::new(raster_table()) })
    }

    /// Renders the view centred on `centre` (RGB).
    #[must_use]
    pub fn render(&self, town: &Town, centre: Vec2, ego: Obb, vehicles: &[SceneBox], route: &Route, closest_waypoint: usize) -> Image {
        let n = self.cfg.size;
        let m = self.cfg.metres_per_pixel;
        let mut img = Image::new(n, n, 3);
        let half = n as f32 / 2.0;
        let to_world = |x: f32, y: f32| centre + Vec2::new((x - half) * m, (half - y) * m);
        let to_pixel = |p: Vec2| Vec2::new((p.x - centre.x) / m + half, half - (p.y - centre.y) / m);
        for y in 0..n {
            for x in 0..n {
                let c = self.table[town.map.surface.raw_at(to_world(x as f32 + 0.5, y as f32 + 0.5)) as usize];
                put(&mut img, x as i32, y as i32, c);
            }
        }
        for o in &town.map.overpasses {
            let axis = (o.b - o.a).normalize_or_zero();
            let side = Vec2::new(-axis.y, axis.x) * (o.width / 2.0);
            outline(&mut img, &[o.a - side, o.b - side, o.b + side, o.a + side].map(to_pixel), palette::DECK);
        }
        for (k, o) in town.map.obstacles.iter().enumerate() {
            fill(&mut img, &Obb::from(o).corners().map(to_pixel), palette::obstacle(o.kind, k));
        }
        for v in vehicles {
            fill(&mut img, &v.footprint.corners().map(to_pixel), v.colour);
        }
        let pts = route.path.points();
        for w in pts.windows(2) {
            line(&mut img, to_pixel(w[0]), to_pixel(w[1]), palette::ROUTE);
        }
        for (i, &w) in route.waypoints.iter().enumerate() {
            let (r, c) = if i == closest_waypoint { (3, palette::CLOSEST_WAYPOINT) } else { (1, palette::WAYPOINT) };
            dot(&mut img, to_pixel(w), r, c);
        }
        fill(&mut img, &ego.corners().map(to_pixel), palette::EGO);
        img
    }
}

/// Colours of the vector sensor's overlay: listed objects by kind (vehicle, parked car, walker,
/// prop), a ray's line to its obstacle and to nothing, the road's edge along a ray.
const SENSED: [[u8; 3]; 4] = [[255, 220, 0], [255, 140, 0], [0, 255, 255], [255, 255, 255]];
const RAY_HIT: [u8; 3] = [255, 60, 60];
const RAY_FREE: [u8; 3] = [110, 110, 110];
const ROAD_EDGE: [u8; 3] = [0, 200, 255];

impl BirdsEye {
    /// Draws a vector sensor reading (`Env::vector`, laid out by `cfg` for `variant`) over `img`,
    /// a view rendered around `centre`, for the ego at `ego_pos` heading `ego_heading`: an outline
    /// of each listed object in its kind's colour, each ray's line to its obstacle (red) or its
    /// full length (grey) with a dot where it leaves the road, and the path's waypoints.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_vector(
        &self,
        img: &mut Image,
        centre: Vec2,
        ego_pos: Vec2,
        ego_heading: f32,
        reading: &[f32],
        cfg: &VectorConfig,
        variant: Variant,
    ) {
        let m = self.cfg.metres_per_pixel;
        let half = self.cfg.size as f32 / 2.0;
        let to_pixel = |p: Vec2| Vec2::new((p.x - centre.x) / m + half, half - (p.y - centre.y) / m);
        let axis = dir(ego_heading);
        let to_world = |v: Vec2| ego_pos + Vec2::new(axis.x * v.x - axis.y * v.y, axis.y * v.x + axis.x * v.y);
        let range = cfg.range;
        let mut at = 0;
        for seg in cfg.segments(variant) {
            let values = &reading[at..(at + seg.count * seg.fields).min(reading.len())];
            at += seg.count * seg.fields;
            match seg.name {
                "waypoints" => {
                    for w in values.chunks_exact(2) {
                        dot(img, to_pixel(to_world(Vec2::new(w[0], w[1]) * range)), 1, ROAD_EDGE);
                    }
                }
                "objects" => {
                    for o in values.chunks_exact(seg.fields).filter(|o| o[0] > 0.5) {
                        let body = Box2::with_axis(
                            to_world(Vec2::new(o[1], o[2]) * range),
                            to_world(Vec2::new(o[5], o[6])) - ego_pos,
                            Vec2::new(o[7] * 5.0, o[8] * 2.5),
                        );
                        let kind = (9..13).find(|&k| o[k] > 0.5).map_or(3, |k| k - 9);
                        outline(img, &body.corners().map(to_pixel), SENSED[kind]);
                    }
                }
                "rays" => {
                    let n = seg.count;
                    for (k, r) in values.chunks_exact(RAY_FIELDS).enumerate() {
                        let a = std::f32::consts::TAU * k as f32 / n as f32;
                        let u = Vec2::new(crate::math::cos(a), crate::math::sin(a));
                        let hit = to_world(u * r[0] * range);
                        line(img, to_pixel(ego_pos), to_pixel(hit), if r[0] < 1.0 { RAY_HIT } else { RAY_FREE });
                        if r[1] < 1.0 {
                            dot(img, to_pixel(to_world(u * r[1] * range)), 1, ROAD_EDGE);
                        }
                    }
                }
                _ => {}
            }
        }
    }
}

fn put(img: &mut Image, x: i32, y: i32, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < img.width && (y as u32) < img.height {
        let i = (y as usize * img.width as usize + x as usize) * 3;
        img.data[i..i + 3].copy_from_slice(&c);
    }
}

/// Fills a convex polygon (pixel coordinates).
fn fill(img: &mut Image, poly: &[Vec2], c: [u8; 3]) {
    let (mut lo, mut hi) = (poly[0], poly[0]);
    for p in poly {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let area: f32 = (0..poly.len()).map(|i| cross(poly[i], poly[(i + 1) % poly.len()])).sum();
    let x0 = lo.x.floor().max(0.0) as i32;
    let y0 = lo.y.floor().max(0.0) as i32;
    let x1 = hi.x.ceil().min(img.width as f32) as i32;
    let y1 = hi.y.ceil().min(img.height as f32) as i32;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            if (0..poly.len()).all(|i| cross(poly[(i + 1) % poly.len()] - poly[i], p - poly[i]) * area.signum() >= 0.0) {
                put(img, x, y, c);
            }
        }
    }
}

fn outline(img: &mut Image, poly: &[Vec2], c: [u8; 3]) {
    for i in 0..poly.len() {
        line(img, poly[i], poly[(i + 1) % poly.len()], c);
    }
}

fn line(img: &mut Image, a: Vec2, b: Vec2, c: [u8; 3]) {
    let n = (a.distance(b).ceil() as usize).clamp(1, 4096);
    for k in 0..=n {
        let p = a + (b - a) * (k as f32 / n as f32);
        put(img, p.x as i32, p.y as i32, c);
    }
}

fn dot(img: &mut Image, p: Vec2, r: i32, c: [u8; 3]) {
    for dy in -r..=r {
        for dx in -r..=r {
            put(img, p.x as i32 + dx, p.y as i32 + dy, c);
        }
    }
}
