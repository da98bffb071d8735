//! Environment configuration: every constant of the episode, reward, traffic and vehicle, with
//! the paper's values as defaults. Validated once, with errors that name the field.
//!
//! [`EnvConfig`] gathers the parts; each part's own struct lives beside the code it configures
//! (`RewardConfig` in `reward.rs`, `CameraConfig` in `camera/front.rs`, `IdmParams` in
//! `traffic.rs`, `VehicleParams` in `vehicle.rs`). What those parts share with this file —
//! [`ConfigError`] and [`Variant`] — sits in leaf files below it, so nothing imports this file back.

pub(crate) mod error;
pub(crate) mod variant;

use serde::{Deserialize, Serialize};

pub use self::error::ConfigError;
pub use self::variant::Variant;
use crate::camera::CameraConfig;
use crate::hazards::config::HazardsConfig;
use crate::planner::kind::PlannerKind;
use crate::reward::RewardConfig;
use crate::sensor::VectorConfig;
use crate::traffic::IdmParams;
use crate::vehicle::VehicleParams;

/// Everything an environment needs besides the map, and which map a run drives (`map`: the
/// caller builds the town, `Env::new` takes it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EnvConfig {
    /// `hybrid` (the paper's agent: the network sees d, the reward has r_w) or `end_to_end`
    /// (camera and speed only, no r_w).
    pub variant: Variant,
    /// The town to train on: `default_town` when unset, `held_out_town` or a map file (text format
    /// or OpenDRIVE `.xodr`, relative to the learner's directory); the learner sends it to every
    /// actor.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map: Option<String>,
    /// Simulation step, seconds. The default is the paper's 10 Hz.
    pub dt: f32,
    /// Spacing of the planner's waypoints along the route, metres. The default is the paper's.
    pub waypoint_spacing: f32,
    /// Shortest random training route, metres.
    pub route_length_min: f32,
    /// Longest random training route, metres.
    pub route_length_max: f32,
    /// Steps before a training episode is truncated.
    pub time_limit: u32,
    /// Steps before an evaluation route is truncated. Longer than `time_limit`: waiting at junctions
    /// takes time.
    pub eval_time_limit: u32,
    /// The reward: the paper's (`kind = "paper"`, the default: r = β_v·r_v + β_l·r_l + β_w·r_w
    /// per step, collision and arrival rewards at the end) or route progress (`kind = "progress"`).
    pub reward: RewardConfig,
    /// Other cars.
    pub traffic: TrafficConfig,
    /// The ego vehicle (kinematic bicycle model).
    pub vehicle: VehicleParams,
    /// The front camera (omit the table for none: no image is rendered).
    pub camera: Option<CameraConfig>,
    /// The vector sensor: the world as a list of objects, rays and the planner's path (omit the
    /// table for none). See `sensor`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vector: Option<VectorConfig>,
    /// Hazards the planner does not know: stalled car, pedestrian crossing, cut-in, hard brake,
    /// construction, opposite overtaker, junction runner.
    pub hazards: HazardsConfig,
    /// The planner giving the waypoints (d, path features, the model-based driver): `astar` (the
    /// global route) or `astar+avoid` (bent around perceived hazards and obstacles).
    pub planner: PlannerKind,
}

impl Default for EnvConfig {
    fn default() -> Self {
        Self {
            variant: Variant::Hybrid,
            map: None,
            dt: 0.1,
            waypoint_spacing: 8.0,
            route_length_min: 50.0,
            route_length_max: 150.0,
            time_limit: 200,
            eval_time_limit: 300,
            reward: RewardConfig::default(),
            traffic: TrafficConfig::default(),
            vehicle: VehicleParams::default(),
            camera: Some(CameraConfig::default()),
            vector: None,
            hazards: HazardsConfig::default(),
            planner: PlannerKind::Astar,
        }
    }
}

/// Other road users.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrafficConfig {
    /// Moving traffic cars (0 = empty roads; 60+ = dense on the default town).
    pub vehicles: usize,
    /// Cars parked on the roads' parking shoulders.
    pub parked_cars: usize,
    /// The paper code's option: a parked car on the route, this many metres ahead of the start,
    /// standing in the lane.
    pub parked_car_ahead: Option<f32>,
    /// Traffic keeps at least this far from the ego vehicle when placed, metres.
    pub spawn_clearance: f32,
    /// The Intelligent Driver Model of the traffic cars.
    pub idm: IdmParams,
}

impl Default for TrafficConfig {
    fn default() -> Self {
        Self { vehicles: 20, parked_cars: 12, parked_car_ahead: None, spawn_clearance: 25.0, idm: IdmParams::default() }
    }
}

fn check(ok: bool, field: &str, message: impl FnOnce() -> String) -> Result<(), ConfigError> {
    if ok { Ok(()) } else { Err(ConfigError { field: field.to_owned(), message: message() }) }
}

fn positive(x: f32, field: &str) -> Result<(), ConfigError> {
    check(x.is_finite() && x > 0.0, field, || format!("{x} must be a finite number > 0"))
}

impl EnvConfig {
    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if let Some(m) = &self.map {
            check(!m.trim().is_empty(), "map", || "is empty: name an embedded town (default_town, held_out_town) or a map file".into())?;
        }
        positive(self.dt, "dt")?;
        check(self.dt <= 1.0, "dt", || format!("{} s is too coarse; use at most 1.0", self.dt))?;
        positive(self.waypoint_spacing, "waypoint_spacing")?;
        positive(self.route_length_min, "route_length_min")?;
        check(self.route_length_max >= self.route_length_min, "route_length_max", || {
            format!("{} must be >= route_length_min ({})", self.route_length_max, self.route_length_min)
        })?;
        check(self.time_limit > 0, "time_limit", || "must be at least 1 step".into())?;
        check(self.eval_time_limit > 0, "eval_time_limit", || "must be at least 1 step".into())?;
        self.reward.validate()?;
        let t = &self.traffic;
        check(t.vehicles <= 500, "traffic.vehicles", || format!("{} is more than the supported 500", t.vehicles))?;
        check(t.parked_cars <= 500, "traffic.parked_cars", || format!("{} is more than the supported 500", t.parked_cars))?;
        if let Some(a) = t.parked_car_ahead {
            check(a.is_finite() && a >= 6.0, "traffic.parked_car_ahead", || format!("{a} m must be at least 6 (a car length ahead)"))?;
        }
        check(t.spawn_clearance.is_finite() && t.spawn_clearance >= 0.0, "traffic.spawn_clearance", || {
            format!("{} must be >= 0", t.spawn_clearance)
        })?;
        for (x, f) in [
            (t.idm.accel, "traffic.idm.accel"),
            (t.idm.comfort_decel, "traffic.idm.comfort_decel"),
            (t.idm.max_decel, "traffic.idm.max_decel"),
            (t.idm.min_gap, "traffic.idm.min_gap"),
            (t.idm.headway, "traffic.idm.headway"),
        ] {
            positive(x, f)?;
        }
        let v = &self.vehicle;
        for (x, f) in [
            (v.length, "vehicle.length"),
            (v.width, "vehicle.width"),
            (v.wheelbase, "vehicle.wheelbase"),
            (v.max_accel, "vehicle.max_accel"),
            (v.max_brake, "vehicle.max_brake"),
            (v.max_speed, "vehicle.max_speed"),
            (v.max_steer, "vehicle.max_steer"),
            (v.steer_halving_speed, "vehicle.steer_halving_speed"),
            (v.steer_rate, "vehicle.steer_rate"),
        ] {
            positive(x, f)?;
        }
        check(v.coast_decel.is_finite() && v.coast_decel >= 0.0, "vehicle.coast_decel", || format!("{} must be >= 0", v.coast_decel))?;
        check(v.wheelbase < v.length, "vehicle.wheelbase", || {
            format!("{} must be shorter than vehicle.length ({})", v.wheelbase, v.length)
        })?;
        check(v.max_steer < 1.5, "vehicle.max_steer", || format!("{} rad must be below 1.5 (~86°)", v.max_steer))?;
        if let Some(c) = &self.camera {
            c.validate()?;
        }
        if let Some(v) = &self.vector {
            v.validate()?;
        }
        self.hazards.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_errors_name_fields() {
        EnvConfig::default().validate().unwrap();
        let mut c = EnvConfig::default();
        c.reward.d0 = -1.0;
        assert_eq!(c.validate().unwrap_err().field, "reward.d0");
        let c = EnvConfig { route_length_max: 10.0, ..EnvConfig::default() };
        let e = c.validate().unwrap_err();
        assert_eq!(e.to_string(), "config field `route_length_max`: 10 must be >= route_length_min (50)");
        let mut c = EnvConfig::default();
        c.vehicle.wheelbase = 9.0;
        assert_eq!(c.validate().unwrap_err().field, "vehicle.wheelbase");
        let c = EnvConfig { map: Some(" ".into()), ..EnvConfig::default() };
        assert_eq!(c.validate().unwrap_err().field, "map");
    }
}
