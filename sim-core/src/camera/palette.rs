//! Colours of the world, shared by both views.

use crate::hazards::prop::PropKind;
use crate::map::{ObstacleKind, SHADE, Surface};

pub const SKY_TOP: [u8; 3] = [120, 170, 225];
pub const SKY_HORIZON: [u8; 3] = [200, 220, 235];
/// Ground too far away to resolve.
pub const HAZE: [u8; 3] = [150, 165, 160];
pub const DECK: [u8; 3] = [165, 160, 150];
pub const DECK_UNDERSIDE: [u8; 3] = [70, 68, 66];
pub const EGO: [u8; 3] = [220, 30, 30];
pub const ROUTE: [u8; 3] = [40, 200, 80];
pub const WAYPOINT: [u8; 3] = [30, 120, 255];
pub const CLOSEST_WAYPOINT: [u8; 3] = [255, 0, 255];

/// Walkers: a colour no car, building or surface has.
pub const WALKER: [u8; 3] = [200, 40, 170];

/// The colour of a hazard's prop.
#[must_use]
pub fn prop(kind: PropKind, index: usize) -> [u8; 3] {
    match kind {
        PropKind::Cone => [240, 120, 20],
        PropKind::Barrier => [245, 245, 240],
        PropKind::ParkedCar => CARS[index % CARS.len()],
    }
}

/// Car body colours, picked by vehicle index.
pub const CARS: [[u8; 3]; 8] =
    [[40, 60, 140], [200, 200, 205], [30, 30, 35], [120, 60, 150], [230, 230, 230], [40, 140, 150], [200, 140, 40], [90, 90, 100]];

/// Building colours, picked by obstacle index.
pub const BUILDINGS: [[u8; 3]; 5] = [[176, 150, 120], [150, 140, 135], [190, 175, 150], [130, 115, 105], [165, 125, 95]];

/// The colour of a surface kind.
#[must_use]
pub fn surface(kind: Surface) -> [u8; 3] {
    match kind {
        Surface::Offroad => [86, 120, 62],
        Surface::Sidewalk => [172, 170, 165],
        Surface::Shoulder => [92, 92, 96],
        Surface::Road | Surface::Junction => [70, 70, 74],
        Surface::WhiteLine => [235, 235, 235],
        Surface::YellowLine => [230, 195, 60],
    }
}

/// Colour of every raw raster cell value (surface kind with the shade flag).
#[must_use]
pub fn raster_table() -> [[u8; 3]; 256] {
    let mut t = [[0u8; 3]; 256];
    for (v, entry) in t.iter_mut().enumerate() {
        let c = surface(Surface::from_u8(v as u8));
        *entry = if v as u8 & SHADE != 0 { scale(c, 0.55) } else { c };
    }
    t
}

/// Colour of a static obstacle.
#[must_use]
pub fn obstacle(kind: ObstacleKind, index: usize) -> [u8; 3] {
    match kind {
        ObstacleKind::Building => BUILDINGS[index % BUILDINGS.len()],
        ObstacleKind::Pole => [45, 45, 50],
        ObstacleKind::Pillar => [150, 148, 142],
    }
}

/// A colour scaled by `k` (0–1).
#[must_use]
pub fn scale(c: [u8; 3], k: f32) -> [u8; 3] {
    c.map(|x| (f32::from(x) * k).round().clamp(0.0, 255.0) as u8)
}

/// Integer luma (ITU-R BT.601 weights), for gray images.
#[inline]
#[must_use]
pub fn luma(c: [u8; 3]) -> u8 {
    ((77 * u32::from(c[0]) + 150 * u32::from(c[1]) + 29 * u32::from(c[2])) >> 8) as u8
}
