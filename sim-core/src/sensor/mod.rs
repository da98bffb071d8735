//! The vector sensor (`[env.vector]`): the world as objects, for agents that see a list of numbers
//! instead of pixels. One observation is a flat `f32` vector of fixed layout ([`VectorConfig::segments`]):
//! the ego's own state; for the hybrid agent the planner's path (d, path features, the next
//! waypoints in the ego frame); the nearest objects the ego could see, nearest first, padded with
//! absent slots; and range rays to obstacles and to the road's edge. Every value lies in [−1, 1]
//! (the learner refuses anything else). Nothing privileged beyond the planner's route: an object
//! hidden behind a building or another object is not in the list.
//!
//! The layout is part of what trained checkpoints expect: [`LAYOUT_VERSION`] names it, and actors
//! and learner must agree on it (checked at `Register`). Each field's meaning and scale:
//! docs/MODEL.md, "The vector observation".
//!
//! A reading ([`Sensor::read`]) is plain arithmetic on the state, in a fixed order, with no
//! allocation once its buffers have grown: `ego_path.rs` (the ego and the planner's path),
//! `objects.rs` (gathering, occlusion and the list), `rays.rs`, over `geometry.rs` (boxes, lines of
//! sight) and `statics.rs` (the static obstacles near the ego).

pub mod ego_path;
pub mod geometry;
pub mod objects;
pub mod rays;
pub mod statics;

use serde::{Deserialize, Serialize};

use crate::collision::Obb;
use crate::config::error::ConfigError;
use crate::config::variant::Variant;
use crate::hazards::Hazard;
use crate::math::{Vec2, dir};
use crate::town::Town;
use crate::traffic::Traffic;
use crate::vehicle::{VehicleParams, VehicleState};

use self::ego_path::{PathInput, write_ego, write_path};
use self::objects::{CAMERA_AHEAD, OCCLUDER_MARGIN, Objects};
use self::rays::{RayFan, Targets, edge_distance};
use self::statics::StaticCache;

/// The layout's name: actors send theirs at `Register`, checkpoints record it. Change it whenever
/// a field's meaning, scale or position changes.
pub const LAYOUT_VERSION: &str = "vector/1";

/// The ego's own state: speed, front-wheel angle, longitudinal acceleration.
pub const EGO_FIELDS: usize = 3;
/// The planner's path (hybrid only): d, lateral offset, near and far heading angles.
pub const PATH_FIELDS: usize = 4;
/// Per object: present, x, y, vx, vy (ego frame), cos and sin of its heading relative to the
/// ego's, length, width, and its kind one-hot (vehicle, parked car, walker, prop).
pub const OBJECT_FIELDS: usize = 13;
/// Per ray: distance to the nearest obstacle, distance to the road's edge.
pub const RAY_FIELDS: usize = 2;

/// What the vector sensor reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VectorConfig {
    /// Nearest visible objects listed (K); fewer present are padded with absent slots.
    pub objects: u32,
    /// The planner's next waypoints in the ego frame (M; hybrid only).
    pub waypoints: u32,
    /// Range rays, evenly spaced around the vehicle, the first straight ahead (N).
    pub rays: u32,
    /// Range of objects and rays, metres: farther is absent (objects) or the ray's full length.
    pub range: f32,
}

impl Default for VectorConfig {
    fn default() -> Self {
        Self { objects: 8, waypoints: 5, rays: 16, range: 50.0 }
    }
}

/// A named run of values in the vector: `count` items of `fields` values each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Segment {
    pub name: &'static str,
    pub count: usize,
    pub fields: usize,
}

impl VectorConfig {
    /// Checks every field; the error names it (prefixed `vector.`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let err = |field: &str, message: String| Err(ConfigError { field: format!("vector.{field}"), message });
        if self.objects > 64 {
            return err("objects", format!("{} is more than the supported 64", self.objects));
        }
        if self.waypoints > 32 {
            return err("waypoints", format!("{} is more than the supported 32", self.waypoints));
        }
        if self.rays > 360 {
            return err("rays", format!("{} is more than the supported 360", self.rays));
        }
        if !(self.range.is_finite() && (5.0..=200.0).contains(&self.range)) {
            return err("range", format!("{} m is outside 5..=200", self.range));
        }
        Ok(())
    }

    /// The layout, first to last, for `variant` (the path segments are the hybrid agent's only).
    #[must_use]
    pub fn segments(&self, variant: Variant) -> Vec<Segment> {
        let mut s = vec![Segment { name: "ego", count: 1, fields: EGO_FIELDS }];
        if variant == Variant::Hybrid {
            s.push(Segment { name: "path", count: 1, fields: PATH_FIELDS });
            s.push(Segment { name: "waypoints", count: self.waypoints as usize, fields: 2 });
        }
        s.push(Segment { name: "objects", count: self.objects as usize, fields: OBJECT_FIELDS });
        s.push(Segment { name: "rays", count: self.rays as usize, fields: RAY_FIELDS });
        s
    }

    /// Values in one observation for `variant`: the sum over [`VectorConfig::segments`], worked
    /// out without building them (every reading asks).
    #[must_use]
    pub fn len(&self, variant: Variant) -> usize {
        let path = if variant == Variant::Hybrid { PATH_FIELDS + 2 * self.waypoints as usize } else { 0 };
        EGO_FIELDS + path + OBJECT_FIELDS * self.objects as usize + RAY_FIELDS * self.rays as usize
    }

    /// The layout in words, as checkpoints record it: the version and each segment,
    /// e.g. `vector/1 ego:1x3 path:1x4 waypoints:5x2 objects:8x13 rays:16x2`.
    #[must_use]
    pub fn describe(&self, variant: Variant) -> String {
        let parts: Vec<String> = self.segments(variant).iter().map(|s| format!("{}:{}x{}", s.name, s.count, s.fields)).collect();
        format!("{LAYOUT_VERSION} {}", parts.join(" "))
    }
}

/// What a reading looks at: the state of an environment, by reference.
#[derive(Debug)]
pub struct World<'a> {
    pub town: &'a Town,
    pub vehicle: &'a VehicleParams,
    pub ego: &'a VehicleState,
    /// The ego's speed one step earlier (0 at reset), m/s.
    pub prev_speed: f32,
    /// Step length, seconds.
    pub dt: f32,
    pub traffic: &'a Traffic,
    pub parked: &'a [Obb],
    pub hazard: Option<&'a Hazard>,
    /// The planner's path (hybrid only; `None` leaves the path segments out).
    pub path: Option<PathInput<'a>>,
    /// The reward's d0, the scale of d, metres.
    pub d0: f32,
}

/// The vector sensor: reads a [`World`] into the layout of [`VectorConfig::segments`]. Holds only
/// scratch buffers reused from reading to reading (and a cache of the static obstacles near the
/// ego that no reading depends on), so readings are a function of the world alone.
#[derive(Debug, Clone, Default)]
pub struct Sensor {
    statics: StaticCache,
    objects: Objects,
    fan: RayFan,
    targets: Targets,
}

impl Sensor {
    /// Forgets what was cached about the town (call when the town may have changed).
    pub fn clear(&mut self) {
        self.statics.clear();
    }

    /// Reads `world` under `cfg` into `out` (resized to the layout's length); every value lies in
    /// [−1, 1].
    pub fn read(&mut self, cfg: &VectorConfig, world: &World, out: &mut Vec<f32>) {
        let variant = if world.path.is_some() { Variant::Hybrid } else { Variant::EndToEnd };
        out.clear();
        out.resize(cfg.len(variant), 0.0);
        let ego = world.ego;
        let range = cfg.range;
        let axis = dir(ego.heading);
        let (ego_out, rest) = out.split_at_mut(EGO_FIELDS);
        write_ego(ego_out, ego, world.vehicle, world.prev_speed, world.dt);
        let rest = match &world.path {
            Some(path) => {
                let (path_out, rest) = rest.split_at_mut(PATH_FIELDS);
                let (wp_out, rest) = rest.split_at_mut(2 * cfg.waypoints as usize);
                write_path(path_out, wp_out, path, world.d0, ego, range);
                rest
            }
            None => rest,
        };
        let (obj_out, ray_out) = rest.split_at_mut(OBJECT_FIELDS * cfg.objects as usize);

        self.statics.update(&world.town.statics, ego.pos, range + OCCLUDER_MARGIN);
        self.objects.gather(ego.pos, range, world.traffic, world.parked, world.hazard);
        let camera = ego.pos + axis * CAMERA_AHEAD;
        self.objects.list(cfg.objects as usize, range, camera, &self.statics.near);
        self.objects.write(obj_out, ego.pos, axis, axis * ego.speed, range, 2.0 * world.vehicle.max_speed);

        let surface = &world.town.map.surface;
        let clearance = world.town.edge_clearance.get_or_init(|| rays::EdgeClearance::new(surface));
        self.targets.gather(ego.pos, range, &[&self.objects.boxes, &self.statics.near]);
        for (r, &u) in ray_out.chunks_exact_mut(RAY_FIELDS).zip(self.fan.directions(cfg.rays as usize)) {
            let u = Vec2::new(axis.x * u.x - axis.y * u.y, axis.y * u.x + axis.x * u.y);
            r[0] = self.targets.distance(u, range) / range;
            r[1] = edge_distance(surface, clearance, ego.pos, u, range) / range;
        }

        for v in out.iter_mut() {
            // NaN (a degenerate state) reads as 0.
            *v = if v.is_nan() { 0.0 } else { v.clamp(-1.0, 1.0) };
        }
    }
}

/// The reading an end-to-end agent sees from a hybrid environment's `reading` (same
/// configuration): the hybrid layout without the planner's segments (path and waypoints). Used
/// where an end-to-end agent drives an environment that runs the hybrid variant (evaluation
/// scores every agent in the same world).
#[must_use]
pub fn without_planner(cfg: &VectorConfig, reading: &[f32]) -> Vec<f32> {
    let planner = PATH_FIELDS + 2 * cfg.waypoints as usize;
    debug_assert_eq!(reading.len(), cfg.len(Variant::Hybrid), "a hybrid reading");
    reading[..EGO_FIELDS].iter().chain(&reading[EGO_FIELDS + planner..]).copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_length_is_the_sum_of_the_segments() {
        for cfg in [VectorConfig::default(), VectorConfig { objects: 0, waypoints: 32, rays: 7, range: 20.0 }] {
            for variant in [Variant::Hybrid, Variant::EndToEnd] {
                assert_eq!(
                    cfg.len(variant),
                    cfg.segments(variant).iter().map(|s| s.count * s.fields).sum::<usize>(),
                    "{cfg:?} {variant:?}"
                );
            }
        }
    }
}
