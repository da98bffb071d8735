//! The object list: the objects around the ego (traffic cars, parked cars, a hazard's walkers and
//! props), the nearest `K` of them that the ego could see listed nearest first, each as
//! [`OBJECT_FIELDS`](super::OBJECT_FIELDS) values in the ego's frame.
//!
//! Seeing is the camera's way, all around: an object is listed if some of its sample points (its
//! centre and its four corners) has a clear line of sight from the camera's position (1 m ahead of
//! the ego's centre), blocked neither by a static obstacle nor by another object's box (the ego's
//! own and the object's own do not count).

use crate::collision::Obb;
use crate::hazards::{Hazard, PropKind};
use crate::math::{Vec2, cross, dir};
use crate::traffic::Traffic;

use super::geometry::{Box2, Sight};

/// What an object is: its one-hot slot in the object's fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectKind {
    /// A traffic car that is not parked (moving or stopped in traffic).
    Vehicle = 0,
    /// A parked car: the shoulders' parked cars, traffic cars marked parked (a stalled hazard
    /// car, the parked car ahead), and the parked car a crossing hazard puts on the shoulder.
    Parked = 1,
    Walker = 2,
    /// A cone or barrier of a construction closure.
    Prop = 3,
}

/// One object near the ego.
#[derive(Debug, Clone, Copy)]
pub struct Object {
    pub body: Box2,
    /// World velocity, m/s.
    pub velocity: Vec2,
    pub kind: ObjectKind,
    /// Squared distance from the ego's centre to the object's centre.
    pub dist2: f32,
    /// Orders objects at equal distance: the source (traffic, parked, props, walkers) in the top
    /// bits, the index in it below.
    pub key: u32,
}

/// Objects whose centres lie this much beyond the range are still gathered as occluders and as
/// obstacles for the rays (a box's half diagonal and the camera's offset), metres.
pub const OCCLUDER_MARGIN: f32 = 8.0;

/// How far ahead of the ego's centre the camera is, metres.
pub const CAMERA_AHEAD: f32 = 1.0;

/// The gathered objects and the listing's scratch.
#[derive(Debug, Clone, Default)]
pub struct Objects {
    /// Every object within the range plus [`OCCLUDER_MARGIN`].
    pub near: Vec<Object>,
    /// The objects' boxes, in the order of `near` (for the rays).
    pub boxes: Vec<Box2>,
    /// Indices into `near` of the objects within range, nearest first.
    order: Vec<u32>,
    /// Indices into `near` of the listed objects, nearest first.
    pub listed: Vec<u32>,
}

impl Objects {
    /// Gathers the objects whose centres lie within `range` + [`OCCLUDER_MARGIN`] of `ego`.
    pub fn gather(&mut self, ego: Vec2, range: f32, traffic: &Traffic, parked: &[Obb], hazard: Option<&Hazard>) {
        self.near.clear();
        let reach = range + OCCLUDER_MARGIN;
        let reach2 = reach * reach;
        let push = |near: &mut Vec<Object>, obb: &Obb, axis: Option<Vec2>, velocity: Vec2, kind: ObjectKind, key: u32| {
            let dist2 = obb.centre.distance_squared(ego);
            if dist2 <= reach2 {
                let body = match axis {
                    Some(a) => Box2::with_axis(obb.centre, a, obb.half),
                    None => Box2::new(obb),
                };
                near.push(Object { body, velocity, kind, dist2, key });
            }
        };
        let half = traffic.params.half_extents();
        for (i, c) in traffic.cars.iter().enumerate() {
            if !c.active || c.pos.distance_squared(ego) > reach2 {
                continue;
            }
            let axis = dir(c.heading);
            let kind = if c.parked { ObjectKind::Parked } else { ObjectKind::Vehicle };
            push(&mut self.near, &Obb::new(c.pos, half, c.heading), Some(axis), axis * c.speed, kind, i as u32);
        }
        for (i, p) in parked.iter().enumerate() {
            push(&mut self.near, p, None, Vec2::ZERO, ObjectKind::Parked, (1 << 24) | i as u32);
        }
        if let Some(h) = hazard {
            for (i, p) in h.props.iter().enumerate() {
                let kind = if p.kind == PropKind::ParkedCar { ObjectKind::Parked } else { ObjectKind::Prop };
                push(&mut self.near, &p.body, None, Vec2::ZERO, kind, (2 << 24) | i as u32);
            }
            for (i, w) in h.walkers.iter().enumerate() {
                push(&mut self.near, &w.body(), None, w.velocity(), ObjectKind::Walker, (3 << 24) | i as u32);
            }
        }
        self.boxes.clear();
        self.boxes.extend(self.near.iter().map(|o| o.body));
    }

    /// Lists up to `k` objects within `range` of the ego that the camera at `camera` sees past
    /// `statics` and the other objects, nearest first (ties by key).
    pub fn list(&mut self, k: usize, range: f32, camera: Vec2, statics: &[Box2]) {
        self.order.clear();
        self.listed.clear();
        if k == 0 {
            return;
        }
        let range2 = range * range;
        self.order.extend((0..self.near.len() as u32).filter(|&i| self.near[i as usize].dist2 <= range2));
        let near = &self.near;
        self.order.sort_unstable_by(|&a, &b| {
            let (a, b) = (&near[a as usize], &near[b as usize]);
            a.dist2.total_cmp(&b.dist2).then(a.key.cmp(&b.key))
        });
        for &i in &self.order {
            if self.visible(i as usize, camera, statics) {
                self.listed.push(i);
                if self.listed.len() == k {
                    break;
                }
            }
        }
    }

    /// Whether some sample point of object `i` is in sight of `camera`.
    fn visible(&self, i: usize, camera: Vec2, statics: &[Box2]) -> bool {
        let body = &self.near[i].body;
        let [a, b, c, d] = body.corners();
        [body.centre, a, b, c, d].into_iter().any(|p| {
            let sight = Sight::new(camera, p);
            !self.boxes.iter().enumerate().any(|(j, o)| j != i && o.blocks_sight(&sight)) && !statics.iter().any(|s| s.blocks_sight(&sight))
        })
    }

    /// Writes the listed objects' fields into `out` (`k` slots of `OBJECT_FIELDS`), the absent
    /// slots all zero. The ego is at `ego` heading along the unit `axis`, moving at `ego_velocity`.
    pub fn write(&self, out: &mut [f32], ego: Vec2, axis: Vec2, ego_velocity: Vec2, range: f32, speed_scale: f32) {
        out.fill(0.0);
        let to_ego = |v: Vec2| Vec2::new(v.dot(axis), cross(axis, v));
        for (slot, &i) in out.chunks_exact_mut(super::OBJECT_FIELDS).zip(&self.listed) {
            let o = &self.near[i as usize];
            let p = to_ego(o.body.centre - ego) / range;
            let v = to_ego(o.velocity - ego_velocity) / speed_scale;
            let h = to_ego(o.body.axis);
            slot[..9].copy_from_slice(&[1.0, p.x, p.y, v.x, v.y, h.x, h.y, 2.0 * o.body.half.x / 10.0, 2.0 * o.body.half.y / 5.0]);
            slot[9 + o.kind as usize] = 1.0;
        }
    }
}
