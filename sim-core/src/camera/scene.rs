//! What the renderers draw besides the ground: [`SceneBox`]es, with their heights and colours —
//! cars (built each frame by [`car_box`]) and a map's static scenery (built once per town by
//! [`static_boxes`] and kept in `Town::scene_statics`).
//!
//! The town only stores the list; how scenery looks is decided here, on the camera's side, so
//! that the town knows nothing of the renderers that read it.

use super::palette;
use crate::collision::Obb;
use crate::map::{Map, Overpass};
use crate::math::Vec2;

/// A box standing on the ground (or floating, like an overpass deck) for the renderers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBox {
    pub footprint: Obb,
    /// Height of the bottom face, metres.
    pub bottom: f32,
    /// Height of the top face, metres.
    pub top: f32,
    pub colour: [u8; 3],
}

/// Height of a car's body, metres.
pub const CAR_HEIGHT: f32 = 1.5;

/// A car as a scene box, coloured by its index.
#[must_use]
pub fn car_box(body: Obb, index: usize) -> SceneBox {
    SceneBox { footprint: body, bottom: 0.0, top: CAR_HEIGHT, colour: palette::CARS[index % palette::CARS.len()] }
}

/// A walker as a scene box: 1.8 m tall, in its own colour.
#[must_use]
pub fn walker_box(body: Obb, height: f32) -> SceneBox {
    SceneBox { footprint: body, bottom: 0.0, top: height, colour: palette::WALKER }
}

/// A hazard's prop (cone, barrier, parked car) as a scene box.
#[must_use]
pub fn prop_box(prop: &crate::hazards::prop::Prop, index: usize) -> SceneBox {
    SceneBox { footprint: prop.body, bottom: 0.0, top: prop.height, colour: palette::prop(prop.kind, index) }
}

/// A map's static scenery as the renderers draw it: its obstacles, then its overpass decks.
#[must_use]
pub fn static_boxes(map: &Map) -> Vec<SceneBox> {
    let obstacles = map.obstacles.iter().enumerate().map(|(k, o)| SceneBox {
        footprint: Obb::from(o),
        bottom: 0.0,
        top: o.height,
        colour: palette::obstacle(o.kind, k),
    });
    obstacles.chain(map.overpasses.iter().map(deck_box)).collect()
}

/// The deck of an overpass as a floating box.
fn deck_box(o: &Overpass) -> SceneBox {
    let axis = o.b - o.a;
    let footprint = Obb::new((o.a + o.b) / 2.0, Vec2::new(axis.length() / 2.0, o.width / 2.0), axis.y.atan2(axis.x));
    SceneBox { footprint, bottom: o.clearance, top: o.clearance + o.thickness, colour: palette::DECK }
}
